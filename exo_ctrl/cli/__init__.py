"""The ``exo-ctrl`` command."""

from .app import (
    main,
)

__all__ = [
    "main",
]
