"""``python -m studies COMMAND``: one module per command, each with ``add_command``."""
