"""The world: truth, trajectories, sensor models and the clock. Imports only ``bus``."""
