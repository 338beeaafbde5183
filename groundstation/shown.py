"""How much of a large swarm a person is shown. Beyond ``SHOWN`` vehicles the terminal tables show the
``SHOWN`` worst (groundstation.display). The report's per-vehicle figures do the same, and its swarm
figures show the median and a band instead of a line per vehicle (groundstation.report.figures). The
live view plots the swarm's aggregates (groundstation.layout). Each of them says so. Every vehicle
stays in summary.json, metrics.csv and run.mcap."""

SHOWN = 12
