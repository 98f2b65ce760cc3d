"""What a notebook needs to stop cleanly: `mrclam_dataset`, which ends a notebook in one line
(`NotebookStop`) when the data it needs is not on this machine.

The rest of the notebooks' plumbing lives with its concept: cutting a run in `ekfslam.logs.edit`,
the filter's frame in `ekfslam.analysis.frames_of_reference`, one correction in block form in
`ekfslam.core.steps`, per-lap numbers in `ekfslam.analysis.laps`, Table 1 in
`ekfslam.viz.tables`, partial replays in `ekfslam.pipeline`, answer checks in
`ekfslam.teaching.exercises`.
"""

from __future__ import annotations

from pathlib import Path

from ekfslam.errors import EkfSlamError, InputError
from ekfslam.logs.mrclam.load import find_dataset


class NotebookStop(EkfSlamError):
    """Stops a notebook at this cell. Jupyter shows the message as one line, with no traceback,
    and *Run All* runs no further cell (they need what this one could not give)."""

    def _render_traceback_(self) -> list[str]:  # IPython shows these lines, not a traceback
        return [str(self)]


def mrclam_dataset(n: int = 7) -> Path:
    """The folder of MRCLAM dataset n (`ekfslam.logs.mrclam.load.find_dataset`) for a notebook.

    Raises
    ------
    NotebookStop
        It is not on this machine; the one line says how to fetch it.
    """
    try:
        return find_dataset(n)
    except InputError:
        raise NotebookStop(
            f"MRCLAM Dataset {n} is not on this machine, and the rest of this notebook needs it. "
            f"Fetch it with `python -m ekfslam fetch mrclam {n}` (from its publisher) "
            "and run the notebook again."
        ) from None
