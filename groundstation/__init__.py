"""The ground-station process: scoring against truth, fault control, the run directory, reports and
the MAVLink forward to ground-control software. Imports only ``bus`` (checked by import-linter)."""
