"""The hostile-input corpus (corpus.py) importable by this folder's tests as ``hostile_corpus``."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

_spec = importlib.util.spec_from_file_location(
    "hostile_corpus", Path(__file__).with_name("corpus.py")
)
_corpus = importlib.util.module_from_spec(_spec)
sys.modules["hostile_corpus"] = _corpus
_spec.loader.exec_module(_corpus)
