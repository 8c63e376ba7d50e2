"""The generated reference pages are what the code gives today (tools/make_docs.py)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import tomllib

ROOT = Path(__file__).resolve().parents[1]


def _tool():
    spec = importlib.util.spec_from_file_location("make_docs", ROOT / "tools" / "make_docs.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_committed_reference_pages_are_current() -> None:
    tool = _tool()
    for name, make in tool.PAGES.items():
        assert (ROOT / name).read_text(encoding="utf-8") == make(), name
    assert tool.main(["--check"]) == 0


def test_the_scenario_page_lists_every_key_of_the_template() -> None:
    from exo_ctrl.scenario import scenario_template

    page = (ROOT / "docs" / "scenarios.md").read_text(encoding="utf-8")
    doc = tomllib.loads(scenario_template("paper"))
    for section, table in doc.items():
        assert f"## [{section}]" in page, section
        for key, value in table.items():
            if not isinstance(value, dict):
                assert f"| `{key}` |" in page, (section, key)


def test_the_options_page_lists_the_hidden_options() -> None:
    page = (ROOT / "docs" / "options.md").read_text(encoding="utf-8")
    assert "### exo-ctrl simulate: the long options" in page
    assert "| `--contact {on,off}` |" in page
    assert "| `--set SECTION.KEY=VALUE` |" in page
