"""The documentation as a new user meets it: the site builds strictly (a broken reference
fails), every Python block of the README and of the docs runs, every ``hexapod-pin``
command shown runs, the example notebook executes, the derivations page names tests that
exist, and the typed modules pass mypy. Nothing is downloaded."""

from __future__ import annotations

import ast
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

try:
    import tomllib
except ImportError:                      # Python 3.10
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PAGES = sorted([ROOT / "README.md", *DOCS.rglob("*.md")])
FENCE = re.compile(r"^```(\w+)[^\n]*\n(.*?)^```", re.MULTILINE | re.DOTALL)
#: a first line that marks a block as not to be run (e.g. a partial snippet)
NOT_RUN = "# not run"


def blocks(page: Path, languages: tuple[str, ...]) -> list[str]:
    """The fenced code blocks of a page in the given languages, in order."""
    return [body for lang, body in FENCE.findall(page.read_text(encoding="utf-8"))
            if lang in languages and not body.startswith(NOT_RUN)]


def name(page: Path) -> str:
    return str(page.relative_to(ROOT))


PYTHON_PAGES = [p for p in PAGES if blocks(p, ("python",))]
CLI_PAGES = [p for p in PAGES if any("hexapod-pin " in b for b in blocks(p, ("bash",)))]


def test_every_page_is_in_the_navigation():
    nav = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    for page in DOCS.rglob("*.md"):
        assert str(page.relative_to(DOCS)) in nav, page


def test_the_site_builds_strictly(tmp_path):
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1")
    site = tmp_path / "site"
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-f",
                           str(ROOT / "mkdocs.yml"), "-d", str(site)], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=900, check=False)
    assert done.returncode == 0, done.stderr[-4000:]
    # every signature formatted (mkdocstrings needs ruff or black for that)
    assert "Formatting signatures requires" not in done.stderr + done.stdout
    api = (site / "api" / "hexapod" / "index.html").read_text(encoding="utf-8")
    assert "hexapod_pin.hexapod.kinematics.HexapodKinematics.leg_motion" in api
    # a facade method made by `delegate` shows the component's signature and docstring
    facade = api[api.index('id="hexapod_pin.hexapod.robot.Hexapod.inverse_dynamics"'):][:8000]
    assert "ArrayLike" in facade and "InverseDynamicsResult" in facade
    assert "Served by" in facade and "joint_wrenches" in facade
    derivations = (site / "derivations" / "index.html").read_text(encoding="utf-8")
    # the equation table links into the API reference
    assert 'href="../api/hexapod/#hexapod_pin.hexapod.kinematics.HexapodKinematics.jacobian"' \
        in derivations


@pytest.mark.parametrize("page", PYTHON_PAGES, ids=name)
def test_python_blocks_run(page, tmp_path, monkeypatch):
    """The blocks of one page run in order in one namespace, in a scratch folder."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    namespace: dict = {"__name__": "__main__"}
    for n, block in enumerate(blocks(page, ("python",))):
        exec(compile(block, f"{name(page)} (block {n})", "exec"), namespace)  # noqa: S102


def cli_lines(page: Path) -> list[list[str]]:
    """``hexapod-pin ...`` lines of a page's bash blocks (comments dropped)."""
    out = []
    for block in blocks(page, ("bash",)):
        for line in block.splitlines():
            line = line.split(" #", 1)[0].strip()
            if line.startswith("hexapod-pin "):
                out.append(shlex.split(line)[1:])
            elif "&& hexapod-pin " in line:
                out.append(shlex.split(line.split("&& hexapod-pin ", 1)[1]))
    return out


@pytest.mark.parametrize("page", CLI_PAGES, ids=name)
def test_cli_lines_run(page, tmp_path, monkeypatch):
    """Every command shown succeeds (exit code 0), run in a scratch folder."""
    from hexapod_pin.cli import app

    monkeypatch.chdir(tmp_path)
    runner = CliRunner()
    for args in cli_lines(page):
        result = runner.invoke(app, args)
        assert result.exit_code == 0, (args, result.output[-2000:])


def test_the_notebook_executes(tmp_path):
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    notebook = nbformat.read(ROOT / "examples" / "notebook.ipynb", as_version=4)
    assert all(not cell.get("outputs") for cell in notebook.cells if cell.cell_type == "code")
    client = nbclient.NotebookClient(notebook, timeout=600, kernel_name="python3",
                                     resources={"metadata": {"path": str(tmp_path)}})
    client.execute()
    outputs = [o for cell in notebook.cells if cell.cell_type == "code" for o in cell.outputs]
    assert not [o for o in outputs if o.output_type == "error"]
    html = [o["data"]["text/html"] for o in outputs if "text/html" in o.get("data", {})]
    assert html and html[0].startswith("<iframe") and "hexapodPinCommands" in html[0]
    assert any("image/png" in o.get("data", {}) for o in outputs)


def named_tests_exist(page: str, at_least: int) -> str:
    """Check that every ``tests/...py::test`` a docs page names exists; return its text."""
    text = (DOCS / page).read_text(encoding="utf-8")
    named = re.findall(r"`(tests/[\w/]+\.py)::(\w+)`", text)
    assert len(named) >= at_least
    for path, test in named:
        source = (ROOT / path).read_text(encoding="utf-8")
        assert re.search(rf"^def {test}\(", source, re.MULTILINE), f"{path}::{test}"
    return text


def test_derivations_name_tests_that_exist():
    text = named_tests_exist("derivations.md", 40)
    covered = set()                   # every equation of the seed report has a row
    for first, last in re.findall(r"^\| (\d+)(?:-(\d+))? \|", text, re.MULTILINE):
        covered.update(range(int(first), int(last or first) + 1))
    assert covered == set(range(1, 41))


def test_drive_model_page_names_tests_that_exist():
    named_tests_exist("drives.md", 8)


def test_readme_links_into_the_docs():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    links = re.findall(r"\]\((docs/[^)#]+)", readme)
    assert len(links) >= 5
    for link in links:
        assert (ROOT / link).exists(), link
    assert 'pip install -e ".[test]" && hexapod-pin demo' in readme
    assert "python -m pytest -q" in readme


def test_public_modules_type_check():
    """mypy over the files of ``[tool.mypy]`` in pyproject.toml (the command line, motion
    and geometry files with complete annotations)."""
    pytest.importorskip("mypy")
    done = subprocess.run([sys.executable, "-m", "mypy", "--cache-dir",
                           str(ROOT / ".mypy_cache")], cwd=ROOT, capture_output=True,
                          text=True, timeout=900, check=False)
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-2000:]


def unannotated(source: str) -> list[str]:
    """The public functions and methods of a module's source (module level and public
    classes; compiled kernels, ``@jit...`` / ``@kernel(...)``, excepted) with a parameter or the result not annotated."""
    missing = []

    def visit(node: ast.AST, prefix: str) -> None:
        for item in ast.iter_child_nodes(node):
            if isinstance(item, ast.ClassDef) and not item.name.startswith("_"):
                visit(item, f"{prefix}{item.name}.")
            elif isinstance(item, ast.FunctionDef) and (not item.name.startswith("_")
                                                        or item.name == "__init__"):
                if any("jit" in ast.unparse(d) or ast.unparse(d).startswith("kernel(")
                       for d in item.decorator_list):
                    continue
                a = item.args
                params = [*a.posonlyargs, *a.args, *a.kwonlyargs,
                          *[p for p in (a.vararg, a.kwarg) if p is not None]]
                bare = [p.arg for p in params
                        if p.annotation is None and p.arg not in ("self", "cls")]
                if bare or (item.returns is None and item.name != "__init__"):
                    missing.append(f"{prefix}{item.name}{bare if bare else ' (result)'}")

    visit(ast.parse(source), "")
    return missing


def test_the_annotation_finder_finds_gaps():
    """A test that cannot fail is a defect: the finder sees missing annotations."""
    source = ("def f(x: int) -> int: ...\ndef g(x, y: int) -> None: ...\n"
              "def h(x: int): ...\ndef _p(x): ...\nclass C:\n"
              "    def m(self, *args: int, **kw) -> None: ...\n"
              "    def __init__(self, a: int): ...\n")
    assert unannotated(source) == ["g['x']", "h (result)", "C.m['kw']"]


def test_public_api_is_annotated():
    """Every public function and method of the modules mypy checks has its parameters and
    result annotated (mypy then checks the calls of the whole package against them)."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    files = []
    for entry in config["tool"]["mypy"]["files"]:
        path = ROOT / entry
        files += sorted(path.rglob("*.py")) if path.is_dir() else [path]
    modules = [f for f in files if f.parts[-2] != "tests"]
    assert len(modules) >= 50
    gaps = {str(f.relative_to(ROOT)): unannotated(f.read_text(encoding="utf-8"))
            for f in modules}
    assert {f: g for f, g in gaps.items() if g} == {}


#: a docstring section whose entries name one argument, attribute or exception each
SECTION = re.compile(r"^( *)(Args|Attributes|Raises):\n((?:\1    .*\n|\n(?=\1     ))+)",
                     re.MULTILINE)


def grouped_entries(source: str) -> list[str]:
    """Entries of the Args / Attributes / Raises sections of a module's docstrings that name
    several items (``a, b: ...``, ``a: ...; b: ...``) or, under Raises, no ``Type: when``."""
    bad = []
    for indent, section, body in SECTION.findall(source):
        for line in body.splitlines():
            if not line.startswith(indent + "    ") or line.startswith(indent + "     "):
                continue                                      # a continuation line
            entry = line.strip()
            head = entry.split(":", 1)[0]
            several = "," in head or re.search(r"; (?!default\b)[a-z_]\w*: ", entry)
            if several or (section == "Raises" and not re.match(r"^\w+: ", entry)):
                bad.append(f"{section}: {entry}")
    return bad


def test_the_entry_finder_finds_grouped_entries():
    source = ('    """Doc.\n\n    Args:\n        a, b: two.\n        c: one;\n'
              '            more.\n        d: x; e: y.\n\n    Raises:\n        E, F.\n'
              '        G: when.\n    """\n')
    assert grouped_entries(source) == ["Args: a, b: two.", "Args: d: x; e: y.",
                                       "Raises: E, F."]


def test_docstring_entries_name_one_item():
    """mkdocstrings renders ``a, b: ...`` as one parameter named "a, b" and a Raises entry
    without ``Type:`` as text (the strict build fails on the latter and on unknown
    parameters: ``mkdocs.yml`` keeps griffe's warnings on); Attributes are checked here."""
    config = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    assert "warnings: false" not in config and "warn_unknown_params: true" in config
    found = {str(f.relative_to(ROOT)): grouped_entries(f.read_text(encoding="utf-8"))
             for f in sorted((ROOT / "hexapod_pin").rglob("*.py"))}
    assert {f: g for f, g in found.items() if g} == {}


def test_sphinx_roles_become_links_or_code():
    import importlib.util

    spec = importlib.util.spec_from_file_location("griffe_roles", DOCS / "griffe_roles.py")
    roles = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(roles)
    text = (":class:`~hexapod_pin.core.closed_loop.ClosedLoopModel`, :func:`pin.rnea`, "
            ":meth:`hexapod_pin.Hexapod.jacobian`")
    assert roles.rewrite(text) == ("[`ClosedLoopModel`][hexapod_pin.core.closed_loop."
                                   "ClosedLoopModel], `pin.rnea`, [`hexapod_pin.Hexapod."
                                   "jacobian`][hexapod_pin.Hexapod.jacobian]")


def test_every_module_is_in_the_api_reference():
    import pkgutil

    import hexapod_pin

    listed = set(re.findall(r"^::: (hexapod_pin[\w.]*)", "\n".join(
        page.read_text(encoding="utf-8") for page in (DOCS / "api").glob("*.md")), re.MULTILINE))
    modules = {"hexapod_pin"} | {
        info.name for info in pkgutil.walk_packages(hexapod_pin.__path__, "hexapod_pin.")
        if not info.name.endswith("__main__")}
    assert modules - listed == set(), "add them to a page of docs/api"


def test_the_package_page_lists_every_public_name():
    """docs/api/package.md lists ``hp.__all__``, each name linked to its definition."""
    import hexapod_pin as hp

    page = (DOCS / "api" / "package.md").read_text(encoding="utf-8")
    listed = re.findall(r"^- \[`(\w+)`\]\[([\w.]+)\]", page, re.MULTILINE)
    assert sorted(n for n, _ in listed) == sorted(hp.__all__)
    for n, target in listed:
        obj = getattr(hp, n)
        where = obj.__name__ if hasattr(obj, "__path__") or not hasattr(obj, "__module__") \
            else f"{obj.__module__}.{obj.__qualname__}"
        assert target == where, (n, target)


def test_pages_with_equations_load_mathjax():
    """A page written with $...$ or $$...$$ (pymdownx.arithmatex) is typeset by MathJax."""
    config = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    with_math = [name(p) for p in DOCS.rglob("*.md")
                 if re.search(r"\$\$|(?<![\w$`])\$[^$\s`][^$`]*\$(?![\w$])", p.read_text(encoding="utf-8"))]
    assert with_math, "no page has equations: this test checks nothing"
    assert "pymdownx.arithmatex" in config and "mathjax" in config.lower()
    script = config.split("extra_javascript:")[1].split("\n", 3)
    assert any("javascripts/mathjax.js" in line for line in script)
    assert (DOCS / "javascripts" / "mathjax.js").is_file()
