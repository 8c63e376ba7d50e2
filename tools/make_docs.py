"""Write the generated reference pages: docs/scenarios.md and docs/options.md.

Usage: .venv/bin/python tools/make_docs.py [--check]

docs/scenarios.md is every scenario section and key with its default and
meaning (exo_ctrl/scenario/reference.py); docs/options.md every option of
every subcommand, the long options ``simulate --help`` hides included
(exo_ctrl/cli/reference.py).  Both come from the code; ``--check`` exits 1
when a committed page differs from what the code gives; the test
test_docs_generated runs it.
"""

from __future__ import annotations

import sys
from pathlib import Path

from exo_ctrl.cli.reference import options_markdown
from exo_ctrl.scenario.reference import reference_markdown

ROOT = Path(__file__).resolve().parents[1]
PAGES = {"docs/scenarios.md": reference_markdown, "docs/options.md": options_markdown}


def main(argv: list[str]) -> int:
    check = "--check" in argv
    stale = []
    for name, make in PAGES.items():
        path = ROOT / name
        text = make()
        if check:
            if not path.is_file() or path.read_text(encoding="utf-8") != text:
                stale.append(name)
            continue
        path.write_text(text, encoding="utf-8")
        print(f"wrote {name}")
    if stale:
        print(f"out of date: {', '.join(stale)} (run .venv/bin/python tools/make_docs.py)")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
