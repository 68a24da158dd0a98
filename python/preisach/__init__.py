"""preisach: fast Preisach hysteresis models for piezoceramic actuators.

The simulator, the state (the Preisach boundary) and the Everett table live in the C++
extension :mod:`preisach._core`; this package is the typed Python surface around it.
Volts in, volts out, seconds; relays switch on at ``alpha`` and off at ``beta`` (``alpha >=
beta``), ``r = (alpha - beta) / 2`` and ``s = (alpha + beta) / 2``.
"""

from __future__ import annotations

try:
    from . import _core  # noqa: F401  (fail early, with a clear message, without the extension)
except ImportError as exc:  # pragma: no cover - only without a built extension
    raise ImportError(
        "preisach._core (the compiled C++ core) is missing. Install the package with "
        "`pip install .` (or `pip install -e .`) from the source tree; a plain checkout on "
        "PYTHONPATH has no compiled core."
    ) from exc

from .diagnose import AugmentedModel, DiagnosisReport, diagnose, load_model  # noqa: E402,I001
from .errors import PreisachError, PreisachWarning, RecordingFormatError
from .model import (
    BUILTIN_MODELS,
    PreisachModel,
    SimulationResult,
    Slopes,
    State,
    state_from_dict,
    state_to_dict,
)
from .recording import Recording, RecordingWriter
from .surface import TABLE_3_1, SqrtSurface

__version__ = "0.1.0"

__all__ = [
    "AugmentedModel",
    "BUILTIN_MODELS",
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
    "state_from_dict",
    "state_to_dict",
    "__version__",
]
