"""Tools around the mapper: simulate recordings, evaluate maps, calibrate detectors."""
