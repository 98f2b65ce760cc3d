"""``python -m benchmarks COMMAND``: one module per command, each with ``add_command``."""
