"""One vehicle: pure estimator cores and the fixed-rate node around them. Imports only ``bus``."""
