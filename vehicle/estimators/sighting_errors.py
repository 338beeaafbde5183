"""What a camera sighting's persisting errors add to a filter (``known-map``, ``ekf-slam``): per
sighted subject (a landmark, a robot seen, a robot that sees this one) a Gauss-Markov state for the
range error (a fraction of the range) and one for the bearing error, each when its datasheet field
is nonzero (``range_correlated_sigma_per_m``, ``bearing_correlated_fraction``; the model is
``vehicle.added_states.persisting_sighting``). The filter keeps the states where it likes: it says
where a subject's first state is (``_error_index``, adding them if need be) and what a state's
stationary variance is (``_stationary_variance``).
"""

from __future__ import annotations

from bus.config import SensorSpec
from vehicle.cooperative import CooperativeFix, SeenFix

Subject = tuple[str, int]  # ("landmark", id), ("robot", id seen) or ("seen", id of the robot seeing this one)


class SightingErrors:
    """Mixin of a vehicle estimator: see the module docstring."""

    def _init_sighting_errors(self, spec: SensorSpec) -> None:
        self._range_sigma, self._range_tau = spec.range_correlated_sigma_per_m, spec.range_correlation_s
        self._bearing_fraction, self._bearing_tau = spec.bearing_correlated_fraction, spec.bearing_correlation_s
        self._per_subject = int(bool(self._range_sigma)) + int(bool(self._bearing_fraction))
        self._range_scale: int | None = None  # the camera's range scale state, where the filter keeps one

    def _subject_states(self, bearing_var: float) -> list[tuple[float, float]]:
        """(tau s, stationary variance) of one subject's error states, in order (range, then bearing),
        for sightings reporting bearing variance ``bearing_var`` (rad^2)."""
        return ([(self._range_tau, self._range_sigma**2)] if self._range_sigma else []) + \
            ([(self._bearing_tau, self._bearing_fraction * bearing_var)] if self._bearing_fraction else [])

    def _error_model(self, first: int) -> dict:
        """``added_states.persisting_sighting``'s state arguments for the subject whose error states
        start at ``first``."""
        model: dict = {}
        if self._range_sigma:
            model.update(range_state=first, range_sigma_per_m=self._range_sigma)
        if self._bearing_fraction:
            b = first + int(bool(self._range_sigma))
            model.update(bearing_state=b, bearing_var=self._stationary_variance(b))
        return model

    def _sighting_errors(self, fix: CooperativeFix | SeenFix) -> dict | None:
        """A robot sighting's persisting errors as states (vehicle.cooperative.with_persisting_errors):
        the same camera's as a landmark's, one set per robot seen and one per robot that sees this one;
        this robot's own sightings are read with its camera's range scale too."""
        model = {}
        if self._per_subject:
            key = ("robot", fix.target_id) if isinstance(fix, CooperativeFix) else ("seen", fix.observer_id)
            model = self._error_model(self._error_index(key, fix.stamp_us, float(fix.covariance[1, 1])))
        if isinstance(fix, CooperativeFix) and self._range_scale is not None:
            model["scale_state"] = self._range_scale
        return model or None

    def _error_index(self, key: Subject, t_us: int, bearing_var: float) -> int:
        """Index of the subject's first error state, sighted at ``t_us``."""
        raise NotImplementedError

    def _stationary_variance(self, index: int) -> float:
        """Stationary variance of the error state at ``index``."""
        raise NotImplementedError
