"""Data association for EKF-SLAM: which of a frame's observations is which mapped landmark, from the
innovations and their covariances (``problem``), by Mahalanobis nearest neighbour (``nearest``), joint
compatibility branch and bound (``jcbb``), the improved ant colony (``ant_colony``), and the optimum
of the same gated assignment problem (``optimum``). Pure: no bus, no clock, no OpenCV."""
