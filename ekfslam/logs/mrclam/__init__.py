"""UTIAS MRCLAM: `load` (the parser and its dataset knowledge), `fetch` (the download)."""
