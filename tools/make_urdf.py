"""Regenerate the committed URDFs (urdf/exoskeleton.urdf, urdf/patient.urdf) from the defaults.

Usage: .venv/bin/python tools/make_urdf.py [--check] [--out-dir DIR]

--check writes nothing and exits 1 if a committed file differs from what the
generator produces (for CI).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
if str(REPO) not in sys.path:  # runnable from a checkout without installing the package
    sys.path.insert(0, str(REPO))

from exo_ctrl.model import DEFAULT_URDF_NAMES, BodyParams, urdf_xml, write_urdf  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out-dir", type=Path, default=REPO / "urdf")
    parser.add_argument("--check", action="store_true", help="compare only; exit 1 on a diff")
    args = parser.parse_args(argv)
    stale = []
    for params in (BodyParams.exo_default(), BodyParams.patient_default()):
        path = args.out_dir / DEFAULT_URDF_NAMES[params.kind]
        if args.check:
            current = path.read_bytes() if path.is_file() else b""
            if current != urdf_xml(params).encode("utf-8"):
                stale.append(path)
                print(f"out of date: {path}")
        else:
            args.out_dir.mkdir(parents=True, exist_ok=True)
            print(f"wrote {write_urdf(params, path)}")
    return 1 if stale else 0


if __name__ == "__main__":
    sys.exit(main())
