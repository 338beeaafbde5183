"""Campaigns: many runs of swarmloc (an experiment's, or a user's grid) flown on a Dask cluster, local
by default, each run one task in its own process group, ending in one results table (Parquet).
docs/campaigns.md says how to use it."""
