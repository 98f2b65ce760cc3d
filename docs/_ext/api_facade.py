"""``.. ekfslam-facade::``: the names ``import ekfslam`` gives, made from the package.

The directive is reST (the API index calls it inside ``{eval-rst}``: a MyST page would show
reST handed to it as text). It writes a table of the names, each with its docstring's first
line, and an entry for each under its facade name, ``ekfslam.replay``, so that a link to
``ekfslam.replay`` resolves and the inventory (``objects.inv``) lists it; each entry links to
the full one where the name is defined (``ekfslam.pipeline.replay``). The table is made from
``ekfslam.__all__`` at each build, so a name added to the facade appears without an edit to the
book. A short name in a signature (``RunLog``) that both entries answer to links to the
definition (`FacadeAwarePython`).
"""

from __future__ import annotations

import inspect

from docutils import nodes
from docutils.statemachine import StringList
from sphinx.domains.python import PythonDomain
from sphinx.util.docutils import SphinxDirective

import ekfslam

#: a default longer than this is shown as ``...`` in the facade's signature (its full entry
#: shows it all): ``simulate``'s arena default is the whole seed arena's repr
LONGEST_DEFAULT = 24


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


def short_signature(function) -> str:
    """`function`'s parameters without annotations, long defaults elided."""
    signature = inspect.signature(function)
    parameters = []
    for p in signature.parameters.values():
        p = p.replace(annotation=inspect.Parameter.empty)
        if p.default is not inspect.Parameter.empty and len(repr(p.default)) > LONGEST_DEFAULT:
            p = p.replace(default=Ellipsis)
        parameters.append(p)
    text = str(signature.replace(parameters=parameters, return_annotation=inspect.Signature.empty))
    return text.replace("=Ellipsis", "=...")


def summary(value) -> str:
    doc = inspect.getdoc(value) or ""
    return doc.split("\n\n", 1)[0].replace("\n", " ").strip()


def entries() -> list[str]:
    """The reST of the facade's table and of one entry per name under ``ekfslam``."""
    lines = [".. autosummary::", "   :nosignatures:", ""]
    lines += [f"   ~ekfslam.{name}" for name in ekfslam.__all__]
    lines += ["", ".. py:currentmodule:: ekfslam", ""]
    for name, defined in zip(ekfslam.__all__, facade(), strict=True):
        value = getattr(ekfslam, name)
        if inspect.isclass(value):
            lines.append(f".. py:class:: {name}")
        elif callable(value):
            lines.append(f".. py:function:: {name}{short_signature(value)}")
        else:
            lines.append(f".. py:data:: {name}")
        lines += ["   :module: ekfslam", ""]
        text = summary(value) if (inspect.isclass(value) or callable(value)) else ""
        lines.append(f"   ``import ekfslam`` gives it; its entry: :py:obj:`{defined}`. {text}")
        lines.append("")
    lines += [".. py:currentmodule:: None", ""]
    return lines


class FacadeTable(SphinxDirective):
    def run(self) -> list[nodes.Node]:
        box = nodes.container()
        self.state.nested_parse(StringList(entries(), source="ekfslam.__all__"), 0, box)
        return box.children


def is_facade(name: str) -> bool:
    """True for a facade entry's name (``ekfslam.replay``), False for a definition's."""
    module, _, short = name.rpartition(".")
    return module == "ekfslam" and short in ekfslam.__all__


class FacadeAwarePython(PythonDomain):
    """Python's domain, where a short name that both the facade and its definition answer to
    (``RunLog`` in a signature) means the definition: the facade's entry only points at it.
    A link that names the facade's entry (``ekfslam.replay``) still finds it."""

    def find_obj(self, env, modname, classname, name, type, searchmode=0):
        matches = super().find_obj(env, modname, classname, name, type, searchmode)
        if len(matches) > 1:
            defined = [m for m in matches if not is_facade(m[0])]
            matches = defined or matches
        return matches


def setup(app):
    app.add_directive("ekfslam-facade", FacadeTable)
    app.add_domain(FacadeAwarePython, override=True)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
