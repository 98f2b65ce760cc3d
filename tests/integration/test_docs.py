"""The book's API reference covers the package, and its two extensions do what they say.

The coverage test reads the object inventory of the built book (``docs/_build/html/objects.inv``,
what ``python -m sphinx -W -b html docs docs/_build/html`` writes; CI builds it before the tests).
Where it is absent the test skips with that command; in CI that is a failure. Its list of public
names is made here from the package, not from the book: every module of ``ekfslam`` (but the
private ``_name`` ones and ``__main__``), every class and function a module defines whose name has
no leading underscore, and every name ``import ekfslam`` gives.
"""

from __future__ import annotations

import importlib
import inspect
import json
import os
import pkgutil
import re
import sys
import zlib
from pathlib import Path

import pytest

import ekfslam

REPO = Path(__file__).resolve().parents[2]
DOCS = REPO / "docs"
SITE = DOCS / "_build" / "html"
BUILD = "python -m sphinx -W -b html docs docs/_build/html"

sys.path.insert(0, str(DOCS / "_ext"))
sphinx = pytest.importorskip(
    "sphinx", reason="the book's tools: pip install -r requirements-test.txt"
)
import api_facade  # noqa: E402  (docs/_ext, after sphinx is known to be here)
import book_notebooks  # noqa: E402
import house_docstrings  # noqa: E402


def _in_ci() -> bool:
    return os.environ.get("CI", "").lower() in {"1", "true", "yes"}


def inventory(path: Path) -> dict[str, tuple[str, str]]:
    """{name: (role, page)} of a Sphinx object inventory (version 2)."""
    header, _, _, _, body = path.read_bytes().split(b"\n", 4)
    assert header == b"# Sphinx inventory version 2"
    entries = {}
    for line in zlib.decompress(body).decode("utf-8").splitlines():
        match = re.match(r"(\S+) (\S+:\S+) -?\d+ (\S+) ", line)
        if match:
            entries[match[1]] = (match[2], match[3].split("#")[0])
    return entries


def public_names() -> dict[str, str]:
    """{dotted name: what it is} of everything a user of the package may import."""
    names = {}
    for info in pkgutil.walk_packages(ekfslam.__path__, "ekfslam."):
        last = info.name.rsplit(".", 1)[1]
        if last.startswith("_"):
            continue
        module = importlib.import_module(info.name)
        names[info.name] = "module"
        for name, value in vars(module).items():
            defined_here = getattr(value, "__module__", None) == info.name
            if not name.startswith("_") and defined_here and inspect.isclass(value):
                names[f"{info.name}.{name}"] = "class"
            elif not name.startswith("_") and defined_here and inspect.isfunction(value):
                names[f"{info.name}.{name}"] = "function"
    return names


@pytest.fixture(scope="module")
def built() -> dict[str, tuple[str, str]]:
    objects = SITE / "objects.inv"
    if not objects.is_file():
        reason = f"the book is not built ({objects} missing): {BUILD}"
        if _in_ci():
            pytest.fail(reason + "; CI builds it before the tests (.ci/run)")
        pytest.skip(reason)
    return inventory(objects)


def test_public_names_are_found_where_expected():
    names = public_names()
    assert names["ekfslam.pipeline.replay"] == "function"
    assert names["ekfslam.logs.arrays.run_from_arrays"] == "function"
    assert names["ekfslam.core.filter.ekf.EKFSLAM"] == "class"
    assert "ekfslam.analysis._alignment_solver" not in names
    assert not any(name.startswith("ekfslam.__main__") for name in names)
    assert len(names) > 500


def test_every_public_name_has_an_entry_in_the_api_reference(built):
    missing = [name for name in public_names() if name not in built]
    assert not missing, f"{len(missing)} public names have no API entry: {missing[:20]}"
    for name, (_, page) in built.items():
        if name.startswith("ekfslam"):
            assert (SITE / page).is_file(), f"{name}: its page {page} was not written"


def test_every_name_import_ekfslam_gives_has_its_entry_where_it_is_defined(built):
    names = api_facade.facade()  # what the API reference's first table lists
    assert len(names) == len(ekfslam.__all__)
    assert "ekfslam.sim.config.SimulationConfig" in names  # defined there, imported elsewhere
    assert "ekfslam.core.arena.SEED_ARENA" in names
    for name in names:
        assert name in built, f"{name} (in `import ekfslam`) has no API entry"


def test_every_name_import_ekfslam_gives_is_linkable_by_its_facade_name(built):
    """Regression: ``ekfslam.replay`` was not in the inventory, so a link to it resolved
    nowhere and a search found ``ekfslam.pipeline.replay`` only."""
    for name in ekfslam.__all__:
        role, page = built[f"ekfslam.{name}"]
        assert page == "api/index.html", (name, page)
        assert role in {"py:class", "py:function", "py:data", "py:exception"}, (name, role)
    assert built["ekfslam.replay"][0] == "py:function"
    assert built["ekfslam.RunLog"][0] == "py:class"
    assert api_facade.is_facade("ekfslam.replay") and not api_facade.is_facade(
        "ekfslam.pipeline.replay"
    )
    text = (SITE / "api" / "index.html").read_text(encoding="utf-8")
    assert ".. autosummary::" not in text and ":nosignatures:" not in text
    assert 'href="../api/generated/ekfslam.pipeline.html#ekfslam.pipeline.replay"' in text or (
        'href="generated/ekfslam.pipeline.html#ekfslam.pipeline.replay"' in text
    )


def test_a_class_entry_carries_its_fields(built):
    assert built["ekfslam.pipeline.ReplayResult"][0] == "py:class"
    assert built["ekfslam.pipeline.ReplayResult.landmarks"][0] == "py:attribute"
    assert built["ekfslam.core.noise.NoiseConfig"][1] == "api/generated/ekfslam.core.noise.html"


# --- docs/_ext/house_docstrings.py --------------------------------------------------------------


def test_house_entries_become_a_definition_list():
    lines = [
        "What a replay produced.",
        "name : the run's name.",
        "mu, Sigma : the final state (3 + 2n,) and covariance; the only",
        "    n x n object kept.",
        "Then a paragraph.",
    ]
    assert house_docstrings.house_to_rst(lines) == [
        "What a replay produced.",
        "",
        "name",
        "    the run's name.",
        "mu, Sigma",
        "    the final state (3 + 2n,) and covariance; the only",
        "    n x n object kept.",
        "",
        "Then a paragraph.",
    ]
    assert house_docstrings.rst_problems(house_docstrings.house_to_rst(lines)) == {}
    assert house_docstrings.rst_problems(lines) != {}  # as written, reST reads it wrong


def test_a_parameter_without_a_type_keeps_its_text_as_the_description():
    lines = ["Parameters", "----------", "x : float", "noise : the R and Q to use (default: Q)."]
    assert house_docstrings.house_to_rst(lines)[2:] == [
        "x : float",  # a type: numpydoc's to show as one
        "noise",
        "    the R and Q to use (default: Q).",
    ]


def test_bars_and_glued_literals_are_escaped_outside_backticks():
    out = house_docstrings.house_to_rst(["|x|, |y| <= 1e7 and ``|z|`` in `Tuner`s."])
    assert out == [r"\|x\|, \|y\| <= 1e7 and ``|z|`` in `Tuner`\ s."]
    assert house_docstrings.rst_problems(out) == {}


def test_what_docutils_cannot_read_is_shown_as_plain_text_and_named():
    lines = ["Summary.", "", "Three layers:", "    indented", "  badly"]
    fixed, problems = house_docstrings.as_plain_text(lines)
    assert problems and house_docstrings.rst_problems(fixed) == {}
    assert fixed[2:] == ["::", "", "    Three layers:", "        indented", "      badly", ""]


def test_a_signature_with_a_dataclass_factory_is_parseable():
    fixed, returns = house_docstrings.process_signature(
        None,
        "class",
        "X",
        None,
        {},
        "(a: int, b: list = <factory>)",
        "TypeAliasForwardRef('Array')",
    )
    assert fixed == "(a: int, b: list = ...)" and returns == "Array"


def test_a_member_without_a_module_is_not_skipped_and_does_not_break_the_build():
    """A sympy function class (``sympy.Function("wrap_angle")``) has ``__module__`` None; the
    skip handler read it as a string and the -W build failed."""
    import sympy

    assert house_docstrings.skip_foreign(None, "class", "x", sympy.Function("f"), False, {}) is None

    class Artist:
        __module__ = "matplotlib.artist"

    assert house_docstrings.skip_foreign(None, "class", "x", Artist, False, {}) is True


# --- docs/_ext/book_notebooks.py ----------------------------------------------------------------


def test_the_notebooks_that_need_mrclam_are_read_off_their_code():
    needs = book_notebooks.mrclam_needs(REPO / "notebooks")
    assert needs["notebooks/09-trust-the-ellipses"] == (7,)
    assert set(needs["notebooks/10-real-robots"]) >= {4, 7}
    assert needs["notebooks/13-five-robots-one-map"] == (7,)
    assert "notebooks/06-full-slam" not in needs


def test_without_the_data_those_notebooks_are_left_unexecuted_with_a_warning_on_their_page():
    nowhere = book_notebooks.unexecuted(REPO / "notebooks", here=lambda n: False)
    assert set(nowhere) == set(book_notebooks.mrclam_needs(REPO / "notebooks"))
    assert book_notebooks.unexecuted(REPO / "notebooks", here=lambda n: True) == {}
    source = (REPO / "notebooks" / "09-trust-the-ellipses.ipynb").read_text(encoding="utf-8")
    cells = json.loads(book_notebooks.marked(source, (7,)))["cells"]
    assert cells[1]["cell_type"] == "markdown" and cells[1]["source"].startswith("```{warning}")
    assert "`python -m ekfslam fetch mrclam 7` fetches" in cells[1]["source"]
    two = json.loads(book_notebooks.marked(source, (4, 7)))["cells"][1]["source"]
    assert "Dataset 4, MRCLAM Dataset 7" in two and "mrclam 4` and `python -m ekfslam fetch" in two
    assert cells[2:] == json.loads(source)["cells"][1:]  # nothing else changed


class _App:
    def __init__(self, missing):
        self.config = type("Config", (), {"ekfslam_unexecuted": missing})()


def test_in_ci_a_missing_dataset_stops_the_build(monkeypatch):
    app = _App({"notebooks/09-trust-the-ellipses": (7,)})
    monkeypatch.setenv("CI", "true")
    with pytest.raises(sphinx.errors.ExtensionError, match=r"MRCLAM data missing.*fetch mrclam 7"):
        book_notebooks.say_what_is_missing(app)
    monkeypatch.setenv("CI", "")
    book_notebooks.say_what_is_missing(app)  # outside CI: said, in red, and the build goes on
    book_notebooks.say_what_is_missing(_App({}))
