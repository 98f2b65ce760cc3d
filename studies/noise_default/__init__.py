"""The default noise and the self-diagnosis of issue 26, chosen and scored on MRCLAM and its
variants. See README.md for the commands and the tables they produce."""
