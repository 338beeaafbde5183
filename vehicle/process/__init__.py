"""One vehicle as a process: its node and loops, what comes in and goes out over the bus, the V2V
epochs, the fusion horizon that orders measurements for the estimator."""
