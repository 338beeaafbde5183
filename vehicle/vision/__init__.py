"""The camera front end of the SLAM estimators: features, thinning, pixel offsets to range-bearing."""
