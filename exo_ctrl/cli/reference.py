"""The command-line reference page (docs/options.md), generated from the parser.

Every subcommand's options with their help; for ``simulate``, the options
``--help`` shows and then the long options it hides (each a setting a
scenario file reaches too).
"""

from __future__ import annotations

import argparse

from .app import DESCRIPTION, build_parser

__all__ = ["options_markdown"]


def _rows(parser: argparse.ArgumentParser, hidden: bool) -> list[str]:
    rows = []
    for action in parser._actions:  # argparse keeps its actions there; no public accessor
        if isinstance(action, argparse._HelpAction):
            continue
        text = getattr(action, "hidden_help", None) if hidden else action.help
        if text is None or text == argparse.SUPPRESS:
            continue
        name = ", ".join(action.option_strings) or (action.metavar or action.dest)
        if action.option_strings and action.nargs != 0:
            metavar = action.metavar or (
                "{" + ",".join(map(str, action.choices)) + "}" if action.choices else "VALUE"
            )
            name += f" {metavar}"
        text = " ".join(text.replace("%%", "%").split()).replace("|", "\\|")
        rows.append(f"| `{name}` | {text} |")
    return rows


def options_markdown() -> str:
    """The command-line reference page (Markdown)."""
    parser = build_parser()
    (sub,) = (a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    lines = [
        "# Command-line options",
        "",
        DESCRIPTION,
        "",
        "This page is generated from the parser (`.venv/bin/python tools/make_docs.py`).",
    ]
    for name, command in sub.choices.items():
        lines += ["", f"## exo-ctrl {name}", "", (command.description or "").strip(), ""]
        lines += ["| option | meaning |", "|---|---|", *_rows(command, hidden=False)]
        hidden = _rows(command, hidden=True)
        if hidden:
            lines += [
                "",
                f"### exo-ctrl {name}: the long options",
                "",
                "Hidden from `--help`: each is another spelling of the scenario key it names, "
                "its meaning, unit and default read from the dataclasses (as the scenario "
                "file's comments are).  Beside a scenario file or a preset they override its "
                "keys, as `--set section.key=value` does (the long options first, then "
                "`--set`).  Given alone they describe a run on the `paper-free-air` preset "
                "(`SimConfig()`'s defaults, the defaults shown here) lasting its ramp-in and "
                "two gait cycles.",
                "",
                "| option | meaning |",
                "|---|---|",
                *hidden,
            ]
    return "\n".join(lines) + "\n"
