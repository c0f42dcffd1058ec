"""Griffe extension of the documentation build: Sphinx roles in docstrings become links.

The docstrings use reStructuredText roles (``:class:`~hexapod_pin.core.closed_loop.ClosedLoopModel```,
``:func:`...```, ``:mod:`...```). Rendered by mkdocstrings they would show as raw text, so
this extension rewrites them before rendering:

* a fully qualified target (``hexapod_pin.xxx``) becomes a cross-reference
  ``[`name`][hexapod_pin.xxx]`` (a leading ``~`` shows the last component only); a target
  that does not exist then fails the strict build, like any broken reference;
* any other target (a short name, a Pinocchio function) becomes inline code.

It also gives a module attribute documented by ``#:`` comment lines just above it (the
Sphinx convention of this code base) that comment as its docstring, and shows a facade's
method bound with ``name = delegate("component", Class.method)`` as a method with that
method's signature (parameters, annotations, result) and docstring, after a line linking to
it: what ``inspect.signature`` and ``help`` show of ``robot.name`` at run time.

Loaded from ``mkdocs.yml`` (``extensions: [docs/griffe_roles.py]``); not part of the package.
"""

from __future__ import annotations

import re
from typing import Any

from griffe import (Attribute, Class, Docstring, Extension, Function, Module, Object,
                    Parameter, Parameters)

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


def delegated_function(attr: Attribute, package: Module) -> Function | None:
    """The facade method ``attr`` (``name = delegate(...)``) as a function with the
    component's signature and docstring; None for any other attribute."""
    match = DELEGATE.match(str(attr.value or "").strip())
    if match is None:
        return None
    component, cls, method = match.groups()
    path = f"{attr.module.imports.get(cls, f'{attr.module.path}.{cls}')}.{method}"
    target = package[path.split(".", 1)[1]] if path.startswith(package.path + ".") else None
    if not isinstance(target, Function):
        return None
    parameters = Parameters(*[Parameter(p.name, annotation=p.annotation, kind=p.kind,
                                        default=p.default)
                              for p in target.parameters if p.name != "self"])
    function = Function(attr.name, lineno=attr.lineno, endlineno=attr.endlineno,
                        parameters=parameters, returns=target.returns)
    source = target.docstring or Docstring("", parent=target)
    function.docstring = Docstring(
        f"Served by [`{cls}.{method}`][{path}] of the component `robot.{component}`, "
        f"under the robot's lock.\n\n{source.value}", parent=function, parser=source.parser,
        parser_options=source.parser_options)
    return function


def classes(module: Module) -> list[Class]:
    """Every class of a package, its submodules included (not aliases)."""
    found: list[Class] = []
    for member in module.members.values():
        if member.is_alias:
            continue
        if isinstance(member, Class):
            found.append(member)
        elif isinstance(member, Module):
            found += classes(member)
    return found


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

    def on_package(self, *, pkg: Module, **kwargs: Any) -> None:
        """Replace each ``delegate`` attribute of the package's classes by a method."""
        for cls in classes(pkg):
            for name, member in list(cls.members.items()):
                if isinstance(member, Attribute):
                    function = delegated_function(member, pkg)
                    if function is not None:
                        cls.set_member(name, function)
