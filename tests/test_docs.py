"""The documentation holds: its Python examples run as written, the README stays a front door, and
``--help`` and the docs' exit-code page come from the one table in ``drive_bridge.errors``."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from drive_bridge.cli import build_parser
from drive_bridge.errors import EXIT_TABLE

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
EXAMPLES = sorted(p for p in DOCS.rglob("*.md") if "```python" in p.read_text(encoding="utf-8"))


@pytest.mark.parametrize("page", EXAMPLES, ids=lambda p: str(p.relative_to(DOCS)))
def test_the_python_examples_of_a_page_run_as_written(page, tmp_path, monkeypatch):
    """Each page's ```python blocks run in order in one namespace, in an empty directory."""
    monkeypatch.chdir(tmp_path)
    blocks = re.findall(r"```python\n(.*?)```", page.read_text(encoding="utf-8"), flags=re.S)
    assert blocks
    namespace: dict = {"__name__": "__docs__"}
    for k, block in enumerate(blocks):
        exec(compile(block, f"{page.name}, example {k + 1}", "exec"), namespace)


def test_the_readme_is_a_front_door():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(readme.splitlines()) <= 150
    for link in re.findall(r"\]\((docs/[^)#]+)", readme):  # every page it points to is there
        assert (ROOT / link).is_file(), link


def test_help_and_the_docs_print_the_one_exit_code_table():
    epilog = build_parser().format_help()
    for code, kind, _ in EXIT_TABLE:
        assert re.search(rf"^\s+{code}\s+{kind}\s", epilog, flags=re.M), (code, kind)
    page = (DOCS / "reference" / "exit-codes.md").read_text(encoding="utf-8")
    assert "{drive-bridge-exit-codes}" in page  # generated, not written by hand
