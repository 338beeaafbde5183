"""The factor bookkeeping of vehicle.models.correlation against the truth: linear vehicles (a random-walk
pose) that fuse each other's broadcasts by turns, one-sided, while a tracker follows the true joint
covariance of their errors under exactly the operations they perform. With two vehicles every
correlation flows through the pair's anchor, so what each vehicle claims (its covariance) and what the
pair's factors give (equation 1) must equal the truth; with more, the third-party terms Luft et al.
leave out make it an approximation (experiments.correlation_study measures how good)."""

from __future__ import annotations

import numpy as np
import pytest

from experiments.correlation_study import Regime, study
from vehicle.models.correlation import Anchor, Claim, ClaimRefused, Factors, fuser_at, resolve
from vehicle.models.correlation_update import joint_is_positive, pair_update, shrinks_at_most_as_independent

PERIOD = 200_000
Q = np.diag([0.02, 0.02, 0.001])  # per epoch
R_REL = np.diag([0.05, 0.05])  # a relative position measurement p_b - p_a
R_GNSS = np.diag([0.5, 0.5])
H_POS = np.hstack([np.eye(2), np.zeros((2, 1))])


class Swarm:
    """n linear vehicles (pose [x, y, yaw] as a random walk) and the truth tracker: the joint covariance
    Sigma (3n, 3n) of their errors under the operations they perform."""

    def __init__(self, n: int, rng: np.random.Generator) -> None:
        self.n, self.rng = n, rng
        self.P = [np.diag([0.1, 0.1, 0.01]) for _ in range(n)]
        self.books = [Factors(3) for _ in range(n)]
        self.Sigma = np.kron(np.eye(n), np.diag([0.1, 0.1, 0.01]))
        self.claims: dict[tuple[int, int], Claim] = {}

    def block(self, i: int) -> slice:
        return slice(3 * i, 3 * i + 3)

    def epoch(self, k: int, pairs: list[tuple[int, int]], gnss: set[int]) -> None:
        t = k * PERIOD
        for i in range(self.n):  # motion
            self.P[i] = self.P[i] + Q
        self.Sigma = self.Sigma + np.kron(np.eye(self.n), Q)
        for i in gnss:  # private updates
            self._private(i)
        for i in range(self.n):  # the broadcasts: clones, then each claim
            self.books[i].start_clone(t, self.P[i], self.P[i].copy(), PERIOD)
        self.claims = {
            (i, j): self.books[i].claim(i + 1, j + 1, t, PERIOD) for a, b in pairs for i, j in ((a, b), (b, a))
        }
        broadcast = [P.copy() for P in self.P]
        for a, b in pairs:
            fuser = fuser_at(t, PERIOD, a + 1, b + 1) - 1
            other = b if fuser == a else a
            self._fuse(fuser, other, broadcast[other])

    def _private(self, i: int) -> None:
        H = H_POS
        S = H @ self.P[i] @ H.T + R_GNSS
        K = self.P[i] @ H.T @ np.linalg.inv(S)
        self.P[i] = self.P[i] - K @ S @ K.T
        self.books[i].gain(K, H)
        L = np.eye(3 * self.n)
        L[self.block(i), self.block(i)] -= K @ H
        noise = np.zeros_like(self.Sigma)
        noise[self.block(i), self.block(i)] = K @ R_GNSS @ K.T
        self.Sigma = L @ self.Sigma @ L.T + noise

    def _fuse(self, a: int, b: int, U: np.ndarray) -> None:
        """a fuses b's broadcast (b's pose now) with z = p_b - p_a."""
        resolved = resolve(self.books[a], a + 1, self.claims[(b, a)], U)
        book = self.books[a]
        if resolved.adopt is not None:
            book.adopt(b + 1, resolved.adopt)
        H_own, H_their = -H_POS, H_POS
        update = pair_update(np.zeros(3), self.P[a], np.zeros(2), H_own, H_their, R_REL, resolved.C, U)
        self.P[a] = update.P
        book.gain(update.K, H_own)
        t = self.claims[(b, a)].epoch_us
        book.set_pair(b + 1, Anchor(a + 1, t), U, update.factor)
        L = np.eye(3 * self.n)
        L[self.block(a), self.block(a)] -= update.K @ H_own
        L[self.block(a), self.block(b)] -= update.K @ H_their
        noise = np.zeros_like(self.Sigma)
        noise[self.block(a), self.block(a)] = update.K @ R_REL @ update.K.T
        self.Sigma = L @ self.Sigma @ L.T + noise

    def cross(self, a: int, b: int) -> np.ndarray:
        """Equation (1) from the two books."""
        pair = self.books[a].pairs.get(b + 1)
        if pair is None:
            return np.zeros((3, 3))
        c_a = self.books[a].column(("pair", b + 1))
        their = self.books[b]
        key = ("pair", a + 1) if a + 1 in their.pairs and their.pairs[a + 1].anchor == pair.anchor else None
        c_b = their.column(key) if key else their.column(("clone", pair.anchor.epoch_us))
        return c_a @ np.linalg.solve(pair.U, c_b.T)

    def expected_nees(self, i: int) -> float:
        return float(np.trace(np.linalg.solve(self.P[i], self.Sigma[self.block(i), self.block(i)])))


def test_two_vehicles_taking_turns_are_exact():
    swarm = Swarm(2, np.random.default_rng(0))
    for k in range(60):
        swarm.epoch(k, [(0, 1)], gnss={0} if k % 5 == 0 else set())
        for i in range(2):
            np.testing.assert_allclose(swarm.P[i], swarm.Sigma[swarm.block(i), swarm.block(i)], rtol=1e-9, atol=1e-12)
        if k >= 1:  # the fuser's factor with the other's clone gives the pair's cross-covariance
            fuser = fuser_at(k * PERIOD, PERIOD, 1, 2) - 1
            np.testing.assert_allclose(
                swarm.cross(fuser, 1 - fuser), swarm.Sigma[swarm.block(fuser), swarm.block(1 - fuser)], atol=1e-10
            )


def test_a_chain_with_luft_et_al_s_map_stays_consistent_and_split_ci_never_over_claims():
    chain = [(0, 1), (1, 2)]
    for regime in (Regime(relative_var=0.05), Regime(relative_var=5.0)):
        luft = study(3, chain, "factors-luft", regime).expected_nees
        assert np.all(np.abs(luft - 3.0) < 0.25), luft  # no cycle: the third-party terms left out are small
        for n, pairs in ((3, chain), (5, [(a, b) for a in range(5) for b in range(a + 1, 5)])):
            assert study(n, pairs, "split-ci", regime).expected_nees.max() <= 3.0 + 1e-6


def test_a_claim_the_book_contradicts_is_refused():
    book = Factors(3)
    book.start_clone(0, np.eye(3), np.eye(3), PERIOD)
    with pytest.raises(ClaimRefused, match="never had"):
        resolve(book, 1, Claim(2, PERIOD, Anchor(1, 0), np.eye(3)), np.eye(3))
    with pytest.raises(ClaimRefused, match="no longer kept"):
        resolve(book, 1, Claim(2, PERIOD, Anchor(2, -PERIOD), np.eye(3)), np.eye(3))
    with pytest.raises(ClaimRefused, match="factor rows"):
        resolve(book, 1, Claim(2, PERIOD, Anchor(2, 0), np.full((3, 3), np.nan)), np.eye(3))
    book.break_pair(2)
    with pytest.raises(ClaimRefused, match="unknown"):
        resolve(book, 1, Claim(2, PERIOD), np.eye(3))


def test_a_fresh_pair_is_uncorrelated():
    book = Factors(5)
    assert not resolve(book, 1, Claim(2, 0), np.eye(3)).C.any()


def test_the_checks_refuse_an_impossible_or_too_generous_correlation():
    P, U = np.diag([1.0, 1.0, 0.1]), np.diag([1.0, 1.0, 0.1])
    assert joint_is_positive(P, 0.5 * np.eye(3) @ np.diag([1.0, 1.0, 0.1]), U)
    assert not joint_is_positive(P, 1.5 * np.eye(3), U)
    H_own, H_their = -H_POS, H_POS
    positive = 0.6 * np.diag([1.0, 1.0, 0.1])  # what fusing each other builds: less to learn
    assert shrinks_at_most_as_independent(P, H_own, H_their, R_REL, positive, U)
    negative = -0.6 * np.diag([1.0, 1.0, 0.1])  # claims more than independence would give
    assert not shrinks_at_most_as_independent(P, H_own, H_their, R_REL, negative, U)


def test_turns_alternate_by_epoch():
    assert [fuser_at(k * PERIOD, PERIOD, 4, 2) for k in range(4)] == [2, 4, 2, 4]
