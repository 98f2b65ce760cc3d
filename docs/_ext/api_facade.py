"""``{ekfslam-facade}``: the table of the names ``import ekfslam`` gives, made from the package.

Each name links to its entry where it is defined, with its docstring's first line. The table is
made from ``ekfslam.__all__`` at each build, so a name added to the facade appears without an
edit to the book.
"""

from __future__ import annotations

import inspect

from docutils import nodes
from docutils.statemachine import StringList
from sphinx.util.docutils import SphinxDirective

import ekfslam


def facade() -> list[str]:
    """The dotted names, where each is defined, of the names ``import ekfslam`` gives."""
    names = []
    for name in ekfslam.__all__:
        value = getattr(ekfslam, name)
        defined = inspect.isclass(value) or inspect.isfunction(value)
        # a class or function where it is defined; data in the module the facade names
        module = value.__module__ if defined else ekfslam._EXPORTS[name]
        names.append(f"{module}.{name}")
    return names


class FacadeTable(SphinxDirective):
    def run(self) -> list[nodes.Node]:
        lines = [".. autosummary::", "   :nosignatures:", ""]
        lines += [f"   ~{name}" for name in facade()]
        box = nodes.container()
        self.state.nested_parse(StringList(lines, source="ekfslam.__all__"), 0, box)
        return box.children


def setup(app):
    app.add_directive("ekfslam-facade", FacadeTable)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
