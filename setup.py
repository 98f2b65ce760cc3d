"""The seed's runs travel inside the package: every wheel holds ``data/runs`` as ``ekfslam/runs``
(`ekfslam.places.seed_run` reads them there), so a notebook finds its data wherever ekfslam is
installed. ``data/runs`` stays the one copy in the repository. And Jupyter's server config that
keeps a checkout's notebooks stored without outputs (`JUPYTER_CONFIG`); everything else is in
pyproject.toml."""

from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

RUNS = Path(__file__).resolve().parent / "data" / "runs"


class BuildWithRuns(build_py):
    """build_py, plus each run folder of ``data/runs`` copied into ``ekfslam/runs``."""

    def run(self) -> None:
        super().run()
        target = Path(self.build_lib) / "ekfslam" / "runs"
        for run in sorted(p for p in RUNS.iterdir() if p.is_dir()):
            self.mkpath(str(target / run.name))
            for path in sorted(p for p in run.iterdir() if p.is_file()):
                self.copy_file(str(path), str(target / run.name / path.name))


# Jupyter's config for every server of the environment the package is installed in: a checkout's
# notebooks are saved without outputs (ekfslam.teaching.clean_save)
JUPYTER_CONFIG = ("etc/jupyter/jupyter_server_config.d", ["jupyter-config/ekfslam.json"])

setup(cmdclass={"build_py": BuildWithRuns}, data_files=[JUPYTER_CONFIG])
