"""The outlier study keeps the 99% gate that the outlier-free consistency study leaves off
(`tests/analysis/test_gate_bias.py` shows why an exact filter needs it off)."""

from __future__ import annotations

import inspect

from ekfslam.analysis.consistency import STUDY_GATE, compare, monte_carlo
from ekfslam.cli.main import build_parser
from ekfslam.core.filter.config import CHI2_2DOF_99
from studies.__main__ import COMMANDS
from studies.robustness import outlier_study


def test_the_outlier_free_study_runs_ungated_and_the_outlier_study_gated():
    # the policy, the same for all three linearisations: no gate where there are no outliers
    assert STUDY_GATE is None
    assert inspect.signature(compare).parameters["gate"].default is None
    assert inspect.signature(monte_carlo).parameters["gate"].default is None
    assert inspect.signature(outlier_study).parameters["gate"].default == CHI2_2DOF_99
    argv = ["consistency", "nees"]
    assert build_parser(argv, COMMANDS).parse_args(argv).gate == 0  # 0: off
    argv = ["consistency", "outliers", "0.05"]
    assert build_parser(argv, COMMANDS).parse_args(argv).gate == CHI2_2DOF_99
