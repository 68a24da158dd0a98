"""preisach: fast Preisach hysteresis models for piezoceramic actuators.

The simulator, the state (the Preisach boundary) and the Everett table live in the C++
extension :mod:`preisach._core`; this package is the typed Python surface around it.
Volts in, volts out, seconds; relays switch on at ``alpha`` and off at ``beta`` (``alpha >=
beta``), ``r = (alpha - beta) / 2`` and ``s = (alpha + beta) / 2``.

The package face is lazy (PEP 562): ``import preisach`` loads only the compiled core and the
error types; every name below is imported from its module on first use, so ``import preisach``
does not pay for :mod:`preisach.diagnose`, :mod:`scipy.signal` or matplotlib. The layers and
what each may import are drawn in ``docs/ARCHITECTURE.md``.
"""

from __future__ import annotations

import importlib
import sys
import types
from typing import TYPE_CHECKING, Any

try:
    from . import _core  # noqa: F401  (fail early, with a clear message, without the extension)
except ImportError as exc:  # pragma: no cover - only without a built extension
    raise ImportError(
        "preisach._core (the compiled C++ core) is missing. Install the package with "
        "`pip install .` (or `pip install -e .`) from the source tree; a plain checkout on "
        "PYTHONPATH has no compiled core."
    ) from exc

from .errors import PreisachError, PreisachWarning, RecordingFormatError

if TYPE_CHECKING:  # the static view of the lazy names below
    from .diagnose import AugmentedModel, DiagnosisReport, diagnose, load_model
    from .model import (
        BUILTIN_MODELS,
        BatchResult,
        PreisachModel,
        SimulationResult,
        Slopes,
        State,
        state_from_dict,
        state_to_dict,
    )
    from .recording import Recording, RecordingWriter, as_recordings
    from .surface import TABLE_3_1, SqrtSurface

#: Public name -> module (relative to this package) it is loaded from on first access.
_LAZY: dict[str, str] = {
    "AugmentedModel": ".diagnose",
    "DiagnosisReport": ".diagnose",
    "diagnose": ".diagnose",
    "load_model": ".diagnose",
    "BUILTIN_MODELS": ".model",
    "BatchResult": ".model",
    "PreisachModel": ".model",
    "SimulationResult": ".model",
    "Slopes": ".model",
    "State": ".model",
    "state_from_dict": ".model",
    "state_to_dict": ".model",
    "Recording": ".recording",
    "RecordingWriter": ".recording",
    "as_recordings": ".recording",
    "SqrtSurface": ".surface",
    "TABLE_3_1": ".surface",
}

__all__ = [
    "AugmentedModel",
    "BUILTIN_MODELS",
    "BatchResult",
    "DiagnosisReport",
    "diagnose",
    "load_model",
    "PreisachError",
    "PreisachModel",
    "PreisachWarning",
    "Recording",
    "RecordingFormatError",
    "RecordingWriter",
    "SimulationResult",
    "Slopes",
    "SqrtSurface",
    "State",
    "TABLE_3_1",
    "as_recordings",
    "state_from_dict",
    "state_to_dict",
    "__version__",
]


def _version() -> str:
    """Return the installed distribution's version (``"0+unknown"`` when not installed)."""
    from importlib import metadata

    try:
        return metadata.version("preisach")
    except metadata.PackageNotFoundError:  # pragma: no cover - a plain source checkout
        return "0+unknown"


def __getattr__(name: str) -> Any:
    """Load a public name from its module on first access (PEP 562)."""
    if name == "__version__":
        value: Any = _version()
    elif name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name], __name__), name)
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    globals()[name] = value  # later look-ups are plain attribute hits
    return value


def __dir__() -> list[str]:
    """List the module's attributes including the lazy public names."""
    return sorted(set(globals()) | set(__all__))


class _Face(types.ModuleType):
    """Module type of this package: ``preisach.diagnose`` stays the function.

    The name ``diagnose`` is both the subpackage :mod:`preisach.diagnose` and the function
    :func:`preisach.diagnose.diagnose`. Importing the subpackage makes the import system set
    the package attribute to the submodule; this hook keeps the documented public attribute
    (the function) instead, as the eager face did. The subpackage itself stays reachable as
    ``sys.modules["preisach.diagnose"]`` and through ``from preisach.diagnose import ...``.
    """

    def __setattr__(self, name: str, value: Any) -> None:
        if name == "diagnose" and isinstance(value, types.ModuleType):
            value = value.diagnose
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Face
