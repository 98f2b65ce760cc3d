"""The package tests' fixtures (``tests/conftest.py``: the shared data, MRCLAM Dataset 7, the seed's
square run), for the benchmarks' tests: one definition of where the data is and how its absence
skips (or fails in CI)."""

from tests.conftest import (  # noqa: F401 (fixtures and the hook that marks shared_data tests)
    data_missing,
    mrclam7,
    pytest_collection_modifyitems,
    shared_data,
    square,
    square_result,
)
