"""The world's models of the sensors added by the sensor recipe (bus.sensors): one module each, a
``measure`` function the world calls at the sensor's rate."""
