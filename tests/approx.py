"""Comparing results that may differ in a float's last bits: across processes, backends (the
Python steps or the compiled ones, chosen by the compile cache's state) and CPUs."""

from __future__ import annotations

import pytest

#: how far two runs of the same replay may differ: the backends agree to about 1e-12
REL, ABS = 1e-9, 1e-12


def approx_tree(tree, rel: float = REL, abs: float = ABS):
    """`tree` (dicts, lists, tuples of values) with every float a `pytest.approx` of it; names,
    counts and flags compare exactly."""
    if isinstance(tree, dict):
        return {key: approx_tree(value, rel, abs) for key, value in tree.items()}
    if isinstance(tree, list | tuple):
        return type(tree)(approx_tree(value, rel, abs) for value in tree)
    if isinstance(tree, float):
        return pytest.approx(tree, rel=rel, abs=abs, nan_ok=True)
    return tree
