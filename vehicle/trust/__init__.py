"""What a vehicle makes of its neighbours: the neighbour monitor's tests on their fixes, what the
others' word is worth, and the believed neighbours' say on its own GNSS resets. Pure."""
