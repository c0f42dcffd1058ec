"""Griffe extension of the documentation build: Sphinx roles in docstrings become links.

The docstrings use reStructuredText roles (``:class:`~hexapod_pin.core.closed_loop.ClosedLoopModel```,
``:func:`...```, ``:mod:`...```). Rendered by mkdocstrings they would show as raw text, so
this extension rewrites them before rendering:

* a fully qualified target (``hexapod_pin.xxx``) becomes a cross-reference
  ``[`name`][hexapod_pin.xxx]`` (a leading ``~`` shows the last component only); a target
  that does not exist then fails the strict build, like any broken reference;
* any other target (a short name, a Pinocchio function) becomes inline code.

It also gives a module attribute documented by ``#:`` comment lines just above it (the
Sphinx convention of this code base) that comment as its docstring, and a facade's method
bound with ``name = delegate("component", Class.method)`` a docstring pointing at that
method, so that the API reference shows them and references to them resolve.

Loaded from ``mkdocs.yml`` (``extensions: [docs/griffe_roles.py]``); not part of the package.
"""

from __future__ import annotations

import re
from typing import Any

from griffe import Attribute, Docstring, Extension, Object

DELEGATE = re.compile(r"^delegate\(\s*['\"](\w+)['\"]\s*,\s*(\w+)\.(\w+)\s*\)$")
ROLE = re.compile(r":(?:py:)?(?:class|func|meth|mod|attr|data|exc|obj|const):`(~?)([^`<>]+?)`")


def rewrite(text: str) -> str:
    """The docstring text with its Sphinx roles as Markdown links or inline code."""

    def replace(match: re.Match) -> str:
        tilde, target = match.group(1), match.group(2).strip()
        shown = target.rsplit(".", 1)[-1] if tilde else target
        shown = shown.rstrip("()")
        if target.startswith("hexapod_pin."):
            return f"[`{shown}`][{target.rstrip('()')}]"
        return f"`{shown}`"

    return ROLE.sub(replace, text)


def comment_docstring(attr: Attribute) -> str | None:
    """The ``#:`` comment lines right above an attribute's assignment, joined; None if none."""
    lines = attr.module.lines if attr.lineno else []
    found: list[str] = []
    index = (attr.lineno or 0) - 2
    while 0 <= index < len(lines) and lines[index].lstrip().startswith("#:"):
        found.insert(0, lines[index].lstrip()[2:].strip())
        index -= 1
    return " ".join(found) if found else None


def delegate_docstring(attr: Attribute) -> str | None:
    """For ``name = delegate("component", Class.method)``: a line linking to the method."""
    match = DELEGATE.match(str(attr.value or "").strip())
    if match is None:
        return None
    component, cls, method = match.groups()
    path = attr.module.imports.get(cls, f"{attr.module.path}.{cls}")
    return (f"`{cls}.{method}` of the component `robot.{component}` (same arguments): "
            f"see [`{cls}.{method}`][{path}.{method}].")


class SphinxRoles(Extension):
    """Rewrite the Sphinx roles of every docstring and read ``#:`` attribute comments
    (see the module docstring)."""

    def on_instance(self, *, obj: Object, **kwargs: Any) -> None:
        if obj.docstring is None and isinstance(obj, Attribute):
            text = comment_docstring(obj) or delegate_docstring(obj)
            if text:
                obj.docstring = Docstring(text, parent=obj)
        if obj.docstring is not None:
            obj.docstring.value = rewrite(obj.docstring.value)
