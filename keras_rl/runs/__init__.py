"""Running seeds: the episode loop, run folders, signals, provenance and the job runner."""
