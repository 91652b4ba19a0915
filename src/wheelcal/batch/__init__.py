"""Running calibrations: one session end to end, and many in parallel from a pipeline file."""
