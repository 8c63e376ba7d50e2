"""The scenario reference page (docs/scenarios.md), generated from the dataclasses.

Every section and key with its default and meaning, in the order a scenario
file has them; ``tools/make_docs.py`` writes the page and a test checks the
committed page equals this module's output, so it cannot drift from the code.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from ..sim import SimConfig
from ..sim.plain import field_types
from ..sim.scenario_file import (
    AUTO,
    DEVICE_GAIT_KEYS,
    GROUPS,
    ORDER,
    field_docs,
    plain_text,
)
from .load import RecordingParams
from .presets import PRESETS, preset_description

__all__ = ["reference_markdown"]

INTRO = """# Scenario files

A run is one TOML file whose sections mirror `SimConfig`'s parts. Write a
complete, commented one from a preset and edit it:

```bash
.venv/bin/exo-ctrl scenario --list
.venv/bin/exo-ctrl scenario --preset paper --out my_run.toml
.venv/bin/exo-ctrl simulate my_run.toml
```

- A key left out takes its default; `# key =   (unset)` lines are optional
  keys whose default is "not set".
- `.venv/bin/exo-ctrl simulate FILE.toml --set section.key=value` overrides one key
  (repeatable, a TOML value or a bare string; `default` restores the
  default); `--controller`, `--duration`/`--cycles`, `--out`, `--summary`
  and `--no-record` override the file too.
- Paths are relative to the current directory, as on the command line.
- `gait.hip_height` and `gait.step_length` left out or `"auto"` follow the
  exoskeleton: the defaults scaled by its leg length (thigh + shank) over
  the paper device's 1.04 m.
- Unknown sections or keys, values of the wrong type and values out of range
  are refused with the file, the key path and what is allowed (exit 2).
- Every recording and summary carries its complete scenario:
  `.venv/bin/exo-ctrl scenario --from RUN.rrd --out again.toml` writes it back, and
  running that file reproduces the run's summary: bit for bit with PD and
  CT; with the QP, bit for bit in the same process and to the last bits of
  proxsuite's solves in another (docs/performance.md, "Repeating a run").

This page is generated from the code (`.venv/bin/python tools/make_docs.py`);
each key's text is its dataclass's docstring.
"""


def _cell(value: Any) -> str:
    """A default value as a table cell."""
    if value is None:
        return "unset"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_cell(v) for v in value) + "]"
    return repr(value)


def _table(lines: list[str], header: str, cls: type, values: dict[str, Any]) -> None:
    docs = field_docs(cls)
    hints = field_types(cls)
    lines += ["", f"## [{header}]", "", plain_text(cls.__doc__ or "").strip().splitlines()[0], ""]
    lines += ["| key | default | meaning |", "|---|---|---|"]
    nested = []
    for f in dataclasses.fields(cls):
        if not f.init:
            continue
        value = values.get(f.name)
        if dataclasses.is_dataclass(value) or isinstance(value, dict):
            nested.append(f.name)
            continue
        shown = _cell(value)
        if header == "gait" and f.name in DEVICE_GAIT_KEYS:
            shown = f'"{AUTO}" ({shown} for the paper device)'
        text = plain_text(docs.get(f.name, "")).replace("|", "\\|")
        lines.append(f"| `{f.name}` | {shown} | {text} |")
    for name in nested:
        sub = values[name]
        sub = dataclasses.asdict(sub) if dataclasses.is_dataclass(sub) else sub
        _table(lines, f"{header}.{name}", hints[name], sub)


def reference_markdown() -> str:
    """The scenario reference page (Markdown)."""
    lines = [INTRO.rstrip(), "", "## Presets", "", "| preset | what it runs |", "|---|---|"]
    lines += [f"| `{name}` | {preset_description(name)} |" for name in PRESETS]
    config = SimConfig()
    plain = config.to_dict()
    docs = field_docs(SimConfig)
    groups = {group: (about, names) for group, about, names in GROUPS}
    hints = field_types(SimConfig)
    for section in ORDER:
        if section in groups:
            about, names = groups[section]
            lines += ["", f"## [{section}]", "", f"{about[0].upper()}{about[1:]}.", ""]
            lines += ["| key | default | meaning |", "|---|---|---|"]
            for name in names:
                text = plain_text(docs.get(name, "")).replace("|", "\\|")
                lines.append(f"| `{name}` | {_cell(plain[name])} | {text} |")
            continue
        hint = hints[section]
        args = getattr(hint, "__args__", ())
        cls = next((a for a in (hint, *args) if dataclasses.is_dataclass(a)), None)
        if section in ("faults", "session"):
            text = plain_text(docs.get(section, ""))
            kind = "array of tables" if section == "faults" else "table"
            lines += ["", f"## [{section}]" if section == "session" else "## [[faults]]", ""]
            lines += [f"An optional {kind}: {text}", ""]
            if cls is not None:
                _table(lines, section, cls, {})
            continue
        value = plain[section]
        _table(lines, section, cls, value if isinstance(value, dict) else {})
    _table(lines, "recording", RecordingParams, dataclasses.asdict(RecordingParams()))
    return "\n".join(lines) + "\n"
