"""Model-mismatch discovery: where a fitted stiction model and a recording disagree, and why."""
