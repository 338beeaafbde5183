"""Hypothesis profiles: `default` (a few hundred examples per fuzz test, in `make test`) and
`fuzz-long` (10,000 examples, `make fuzz`). Pick one with --hypothesis-profile."""

from hypothesis import HealthCheck, settings

settings.register_profile("default", max_examples=300, deadline=None)
settings.register_profile("fuzz-long", max_examples=10_000, deadline=None,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile("default")
