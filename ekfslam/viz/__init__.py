"""The viz floor: every figure and table formatter.

Imports types only (run time: core, logs, leaves); never computes an estimate."""
