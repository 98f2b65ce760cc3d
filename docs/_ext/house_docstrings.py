"""Our docstrings' house style, read as reStructuredText for the API reference.

The package's docstrings list fields and arguments the way filterpy's do, outside any numpydoc
section::

    name : the run's name.
    mu, Sigma : the final state (3 + 2n,) and covariance; the only n x n object kept.
    association : with ids hidden, every sighting's decision, in the
        order of ``run.detections``.

reStructuredText reads those lines as broken definition lists, and a bar in ``|x| <= 1e7`` as a
substitution. Before numpydoc parses its sections, this turns each such block (outside the
sections) into a definition list and escapes a bar that is not inside backticks. Nothing is dropped:
every line of a docstring is rendered.
"""

from __future__ import annotations

import functools
import io
import re

from docutils.core import publish_doctree
from sphinx.util import logging

logger = logging.getLogger(__name__)

#: numpydoc's section titles: their contents are numpydoc's to parse
SECTIONS = frozenset(
    {
        "Parameters",
        "Other Parameters",
        "Returns",
        "Yields",
        "Receives",
        "Raises",
        "Warns",
        "Warnings",
        "See Also",
        "Notes",
        "References",
        "Examples",
        "Attributes",
        "Methods",
    }
)
#: ``name : description`` or ``a, b : description`` at the docstring's left margin
ENTRY = re.compile(r"^(?P<name>[A-Za-z_*][\w*]*(?:\s*,\s*[A-Za-z_*][\w*]*)*) : (?P<text>.*)$")
#: a bar outside double or single backticks (reST would start a substitution there)
LITERAL = re.compile(r"(``.*?``|`[^`]*`)")


def _is_section(lines: list[str], i: int) -> bool:
    return (
        lines[i].strip() in SECTIONS and i + 1 < len(lines) and set(lines[i + 1].strip()) == {"-"}
    )


def _escape_bars(line: str) -> str:
    """Bars outside backticks escaped (``|x|`` is no substitution); a literal glued to a word
    (```AssociatingFilter`s``) parted from it, as reST needs."""
    if line.lstrip().startswith(("+", "| ")):  # a table's row or a line block: reST's own bars
        return line
    parts = LITERAL.split(line)
    for i in range(2, len(parts), 2):
        if parts[i][:1].isalnum():
            parts[i] = "\\ " + parts[i]
    return "".join(p if i % 2 else p.replace("|", r"\|") for i, p in enumerate(parts))


#: numpydoc's sections of ``name : type`` entries
TYPED = frozenset({"Parameters", "Other Parameters", "Attributes", "Returns", "Yields"})


def _is_a_type(text: str) -> bool:
    """``float``, ``(N, 3) array``, ``NoiseConfig or None``; not ``the R and Q to use: ...``."""
    text = text.strip()
    return (
        len(text) <= 40
        and len(text.split()) <= 4
        and not any(c in text for c in ";:")
        and not text.endswith(".")
    )


def _starts_a_list(line: str, out: list[str]) -> bool:
    if not line.lstrip().startswith(("- ", "* ")) or not out or not out[-1].strip():
        return False
    before = out[-1]
    same_indent = len(before) - len(before.lstrip()) == len(line) - len(line.lstrip())
    return same_indent and not before.lstrip().startswith(("- ", "* "))


def house_to_rst(lines: list[str]) -> list[str]:
    """The docstring's lines with house-style entries outside numpydoc sections as a definition
    list (a term, its text indented below it).

    An entry is a line ``name : text`` at the left margin; the indented lines after it continue
    it. A blank line is put before the first entry of a block and after its last, as reST needs.
    """
    out: list[str] = []
    in_section = ""  # the numpydoc section the line is in, if any
    in_entries = False
    literal_indent: int | None = None  # inside a ``::`` literal block: leave it alone
    for i, line in enumerate(lines):
        stripped = line.strip()
        indent = len(line) - len(line.lstrip())
        if literal_indent is not None:
            if stripped and indent <= literal_indent:
                literal_indent = None
            else:
                out.append(line)
                continue
        if _is_section(lines, i):
            in_section = lines[i].strip()
        if in_section:
            match = ENTRY.match(line)
            if in_section in TYPED and match and not _is_a_type(match["text"]):
                # ``noise : the R and Q to use``: numpydoc would set the text as the type
                out += [match["name"], "    " + _escape_bars(match["text"])]
            else:
                out.append(_escape_bars(line))
            continue
        match = ENTRY.match(line)
        if match:
            if not in_entries and out and out[-1].strip():
                out.append("")
            in_entries = True
            out += [match["name"], "    " + _escape_bars(match["text"])]
            continue
        if in_entries and stripped and indent > 0:
            out.append("    " + _escape_bars(line.lstrip()))
            continue
        if in_entries and stripped:
            out.append("")  # the list ends before this line
        elif _starts_a_list(line, out):
            out.append("")  # reST needs a blank line between a paragraph and its list
        in_entries = False
        out.append(_escape_bars(line))
        if stripped.endswith("::"):
            literal_indent = indent
    return out


#: docutils alone does not know Sphinx's roles and directives: those are not problems here
SPHINX_ONLY = ("Unknown interpreted text role", "Unknown directive type", "No role entry for")
INLINE_MARKUP = re.compile(r"[*`]")  # bars are escaped already (_escape_bars)
PROBLEM_LINE = re.compile(r"^<string>:(\d+): \((?:WARNING|ERROR|SEVERE)/\d\) (.*)$")


def rst_problems(lines: list[str], env=None) -> dict[int, str]:
    """{0-based line: problem} of what docutils says about these lines as reST.

    `env`: the Sphinx build's, which Sphinx's roles (the default role included) need.
    """
    return dict(_problems("\n".join(lines), env))


@functools.lru_cache(maxsize=4096)  # autosummary's tables read each docstring a second time
def _problems(text: str, env) -> tuple[tuple[int, str], ...]:
    stream = io.StringIO()
    settings = {"report_level": 2, "halt_level": 5, "warning_stream": stream, "env": env}
    publish_doctree(text, settings_overrides=settings)
    problems = {}
    for line in stream.getvalue().splitlines():
        match = PROBLEM_LINE.match(line)
        if match and not match[2].startswith(SPHINX_ONLY):
            problems.setdefault(max(int(match[1]) - 1, 0), match[2])
    return tuple(problems.items())


def _first_section(lines: list[str]) -> int:
    return next((i for i in range(len(lines)) if _is_section(lines, i)), len(lines))


def _block(lines: list[str], i: int) -> tuple[int, int]:
    """The paragraph around line i: [start, end) of its run of non-blank lines."""
    i = min(i, len(lines) - 1)
    while i > 0 and not lines[i].strip():
        i -= 1
    start, end = i, i + 1
    while start > 0 and lines[start - 1].strip():
        start -= 1
    while end < len(lines) and lines[end].strip():
        end += 1
    return start, end


def as_plain_text(lines: list[str], env=None) -> tuple[list[str], list[str]]:
    """`lines` with each paragraph that is not valid reST (before the numpydoc sections) shown
    as a literal block, and what was wrong with each: every word kept, and no warning."""
    said: list[str] = []
    for _ in range(5):
        problems = rst_problems(lines, env)
        limit = _first_section(lines)
        blocks = sorted({_block(lines, i) for i in problems if i < limit and lines})
        if not blocks:
            break
        said += [problems[i] for i in problems if i < limit]
        for start, end in reversed(blocks):
            if lines[start].strip() == "::":
                continue
            if start == 0:  # the summary: numpydoc dedents what follows it, so no literal block
                text = [INLINE_MARKUP.sub(r"\\\g<0>", line) for line in lines[start:end]]
                lines = [*text, *lines[end:]]
                continue
            text = [" " * 4 + line.rstrip() for line in lines[start:end]]
            lines = [*lines[:start], "::", "", *text, "", *lines[end:]]
    return lines, said


PLAIN: dict[str, list[str]] = {}  # docstrings shown in part as plain text, and why


def process_docstring(app, what, name, obj, options, lines: list[str]) -> None:
    lines[:], problems = as_plain_text(house_to_rst(lines), app.env)
    if problems:
        PLAIN[name] = problems


def report(app, exception) -> None:
    if PLAIN and exception is None:
        logger.info(
            f"{len(PLAIN)} docstrings shown in part as plain text (not valid reST): "
            + "; ".join(f"{name} ({problems[0]})" for name, problems in sorted(PLAIN.items()))
        )


ALIAS_REPR = re.compile(r"TypeAliasForwardRef\('([\w.]+)'\)")


def process_signature(app, what, name, obj, options, signature, return_annotation):
    """Signatures Sphinx can parse into parameters: a dataclass field's ``default_factory``
    shows as ``<factory>`` (not Python: the whole signature fell back to plain text), and an
    alias inside a generic as its repr."""
    if signature is None:
        return None
    fixed = ALIAS_REPR.sub(r"\1", signature.replace("<factory>", "..."))
    returns = return_annotation and ALIAS_REPR.sub(r"\1", return_annotation)
    return fixed, returns


def skip_foreign(app, what, name, obj, skip, options):
    """A matplotlib artist's generated ``set`` is matplotlib's to document, not ours."""
    if what == "class" and (getattr(obj, "__module__", None) or "").startswith("matplotlib"):
        return True
    return None


def setup(app):
    app.connect("autodoc-process-docstring", process_docstring, priority=400)  # before numpydoc
    app.connect("autodoc-skip-member", skip_foreign)
    app.connect("autodoc-process-signature", process_signature)
    app.connect("build-finished", report)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
