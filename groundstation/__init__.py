"""Ground station: scoring, run directory, reports, the `swarm` CLI and launcher. Imports only ``bus``."""
