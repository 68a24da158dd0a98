"""The augmented model: a Preisach model with the physics blocks diagnosis kept.

``AugmentedModel`` = input blocks -> :class:`~preisach.PreisachModel` -> output blocks.  It
simulates like a :class:`~preisach.PreisachModel` (``simulate(u, state=None, ...)`` returns a
:class:`~preisach.SimulationResult`), saves to a versioned ``.npz`` file and loads back
exactly; :func:`load_model` reads either kind of model file.
"""

from __future__ import annotations

import json
import os
import zipfile
from collections.abc import Sequence
from typing import Any, Union

import numpy as np
from numpy.typing import ArrayLike

from .. import _core
from .._io import atomic_write, npz_load_error
from ..model import PreisachModel, SimulationResult, State
from .effects import (
    EffectBlock,
    FeedbackBlock,
    effect_from_dict,
)

__all__ = ["AugmentedModel", "load_model"]

PathLike = Union[str, "os.PathLike[str]"]
_FORMAT = "preisach-augmented-model"
#: version 2: the base's interpolation (``interpolation``, written for a cubic base only)
_FORMAT_VERSION = 2


class AugmentedModel:
    """A Preisach model between input-side and output-side physics blocks.

    Parameters
    ----------
    base : PreisachModel
        The classical Preisach model (V in, V out).
    blocks : sequence of EffectBlock
        Physics blocks; each acts on the input or the output according to its ``side``, in
        the given order within its side.  Their parameters are physical (seconds, hertz,
        volts), so the model simulates at any sample time.
    name : str
        Free-form name, kept by :meth:`save`.
    metadata : dict, optional
        JSON-serialisable information (e.g. the diagnosis that produced it).

    """

    def __init__(
        self,
        base: PreisachModel,
        blocks: Sequence[EffectBlock] = (),
        *,
        name: str = "",
        metadata: dict[str, Any] | None = None,
    ) -> None:
        if not isinstance(base, PreisachModel):
            raise TypeError(f"base: expected a PreisachModel, got {type(base).__name__}")
        for b in blocks:
            if not isinstance(b, EffectBlock):
                raise TypeError(f"blocks: expected EffectBlock instances, got {type(b).__name__}")
        self.base = base
        self.blocks: list[EffectBlock] = list(blocks)
        self.name = name or base.name
        self.metadata: dict[str, Any] = dict(metadata or {})

    @property
    def input_blocks(self) -> list[EffectBlock]:
        """Blocks before the Preisach operator."""
        return [b for b in self.blocks if b.side == "input"]

    @property
    def feedback_blocks(self) -> list[FeedbackBlock]:
        """Output-feedback blocks: they change how the Preisach operator runs (one is used)."""
        return [b for b in self.blocks if isinstance(b, FeedbackBlock)]

    @property
    def output_blocks(self) -> list[EffectBlock]:
        """Blocks after the Preisach operator."""
        return [b for b in self.blocks if b.side == "output"]

    # the PreisachModel surface that callers use for states and ranges
    @property
    def u_min(self) -> float:
        """Lower end of the input range (V)."""
        return self.base.u_min

    @property
    def u_max(self) -> float:
        """Upper end of the input range (V)."""
        return self.base.u_max

    def negative_saturation(self) -> State:
        """Every relay at -1 (see :meth:`PreisachModel.negative_saturation`)."""
        return self.base.negative_saturation()

    def positive_saturation(self) -> State:
        """Every relay at +1."""
        return self.base.positive_saturation()

    def anhysteretic_state(self) -> State:
        """Return the anhysteretic state of the base model."""
        return self.base.anhysteretic_state()

    def neutral_state(self, l: float) -> State:  # noqa: E741
        """Neutral state psi_n^l of the base model."""
        return self.base.neutral_state(l)

    def simulate(
        self,
        u: ArrayLike,
        state: State | None = None,
        t: ArrayLike | None = None,
        *,
        sample_time: float = 1e-3,
        out_of_range: str | None = None,
    ) -> SimulationResult:
        """Simulate the chain for the input samples ``u`` (V).

        Parameters are those of :meth:`PreisachModel.simulate`.  Every block starts in its
        steady state: input blocks at ``state.input``, output blocks at the Preisach output
        of ``state``.  When ``t`` is given its mean spacing is the blocks' sample time.

        Returns
        -------
        SimulationResult
            ``output`` is the chain's output (V); ``extra["preisach_input"]`` and
            ``extra["preisach_output"]`` hold the Preisach operator's own input and output.

        """
        uu = np.ascontiguousarray(u, dtype=float)
        if uu.ndim != 1:
            raise ValueError(f"u: expected a 1-D array of input samples, got shape {uu.shape}")
        bad = np.flatnonzero(~np.isfinite(uu))
        if bad.size:
            raise ValueError(f"u[{int(bad[0])}] is not finite")
        dt = float(sample_time)
        if t is not None:
            tt = np.asarray(t, dtype=float)
            if tt.shape != uu.shape:
                raise ValueError(f"t: shape {tt.shape} does not match u {uu.shape}")
            if tt.size > 1:
                dt = float((tt[-1] - tt[0]) / (tt.size - 1))
        if not dt > 0:
            raise ValueError(f"sample_time: must be positive, got {dt}")
        s0 = self.base.anhysteretic_state() if state is None else state
        x = uu
        x0 = float(s0.input)
        for b in self.input_blocks:
            blk = b.with_dt(dt)
            x0 = blk.reset(x0)
            x = blk.run(x)
        pol = self.base._policy(out_of_range)
        if pol == "raise":
            out = np.flatnonzero((uu < self.base.u_min) | (uu > self.base.u_max))
            if out.size:
                k = int(out[0])
                raise ValueError(
                    f"input u[{k}] = {uu[k]!r} V is outside the model range "
                    f"[{self.base.u_min:g}, {self.base.u_max:g}] V"
                )
        # input blocks may move a clamped input a little outside the range: clamp it back
        x = np.clip(x, self.base.u_min, self.base.u_max)
        fb = self.feedback_blocks
        if fb:
            yp, _, final = fb[-1].simulate(self.base.table, x, s0)
        else:
            res = self.base.simulate(x, s0, t, sample_time=dt, out_of_range="clamp")
            yp, final = res.output, res.final_state
        y = yp
        y0 = self.base.readout(s0)
        for b in self.output_blocks:
            blk = b.with_dt(dt)
            if blk.needs_chain:  # needs the Preisach input (its initial state, the model)
                y = blk.apply_chain(y, x, s0, self.base)
                continue
            y0 = blk.reset(y0)
            y = blk.run(y)
        extra = {"preisach_input": x, "preisach_output": yp}
        return SimulationResult(
            uu,
            np.asarray(y),
            s0,
            final,
            dt,
            self.name,
            extra,
            _time=None if t is None else np.asarray(t, dtype=float),
        )

    # ------------------------------------------------------------------ persistence
    def save(self, path: PathLike) -> None:
        """Write the model to a versioned ``.npz`` file (exact round trip)."""
        info = {
            "name": self.name,
            "metadata": self.metadata,
            "base": {
                "name": self.base.name,
                "metadata": self.base.metadata,
                "out_of_range": self.base.out_of_range,
            },
            "blocks": [b.to_dict() for b in self.blocks],
        }
        arrays: dict[str, Any] = {
            "format": np.array(_FORMAT),
            "version": np.array(2 if self.base.interpolation == "cubic" else 1),
            "levels": self.base.levels,
            "everett": self.base.everett_values,
            "y_min": np.array(self.base.y_min),
            "info": np.array(json.dumps(info)),
        }
        if self.base.interpolation == "cubic":
            arrays["interpolation"] = np.array("cubic")
        atomic_write(path, lambda f: np.savez(f, **arrays), binary=True, what="model")

    @classmethod
    def load(cls, path: PathLike) -> AugmentedModel:
        """Read a model written by :meth:`save`.

        Raises
        ------
        ValueError
            If the file is not an augmented model or its version is newer than supported.

        """
        try:
            f = open(path, "rb")  # opened here: np.load leaks its handle on a bad archive
        except OSError as exc:
            raise ValueError(f"{os.fspath(path)}: not a readable model file ({exc})") from exc
        try:
            data = np.load(f, allow_pickle=False)
        except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
            f.close()
            msg = npz_load_error(exc)
            raise ValueError(f"{os.fspath(path)}: not a readable model file ({msg})") from exc
        if not hasattr(data, "files"):  # a bare .npy array
            f.close()
            raise ValueError(f"{os.fspath(path)}: not a model file (a single array)")
        with f, data:
            if "format" not in data.files or str(data["format"]) != _FORMAT:
                raise ValueError(f"{os.fspath(path)}: not an augmented preisach model file")
            version = int(data["version"])
            if version > _FORMAT_VERSION:
                raise ValueError(
                    f"{os.fspath(path)}: augmented model format version {version} is "
                    f"newer than this package supports ({_FORMAT_VERSION}); upgrade preisach"
                )
            interp = str(data["interpolation"]) if "interpolation" in data.files else "bilinear"
            table = _core.EverettTable(
                data["levels"], data["everett"], float(data["y_min"]), interp
            )
            info = json.loads(str(data["info"]))
        b = info.get("base", {})
        base = PreisachModel(
            table,
            name=b.get("name", ""),
            metadata=b.get("metadata", {}),
            out_of_range=b.get("out_of_range", "clamp"),
        )
        blocks = [effect_from_dict(d) for d in info.get("blocks", [])]
        return cls(base, blocks, name=info.get("name", ""), metadata=info.get("metadata", {}))

    def describe(self) -> str:
        """Describe the chain in one line: ``"... -> PreisachModel(...) -> delay(tau=...)"``."""
        core = repr(self.base)
        if self.feedback_blocks:
            core += " with " + self.feedback_blocks[-1].describe()
        parts = (
            [b.describe() for b in self.input_blocks]
            + [core]
            + [b.describe() for b in self.output_blocks]
        )
        return " -> ".join(parts)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, AugmentedModel):
            return NotImplemented
        return self.base == other.base and [b.to_dict() for b in self.blocks] == [
            b.to_dict() for b in other.blocks
        ]

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        return f"AugmentedModel({self.describe()})"

    def _repr_html_(self) -> str:
        """HTML for Jupyter: the chain of blocks and the Preisach model with its thumbnail."""
        from .._display import augmented_model_html

        return augmented_model_html(self)


def load_model(path: PathLike) -> PreisachModel | AugmentedModel:
    """Load a model file of either kind: a :class:`PreisachModel` or an :class:`AugmentedModel`.

    Raises
    ------
    ValueError
        If the file is neither.

    """
    try:
        with open(path, "rb") as f:  # opened here: np.load leaks its handle on a bad archive
            data = np.load(f, allow_pickle=False)
            if not hasattr(data, "files"):  # a bare .npy array
                raise ValueError("a single array, not an .npz archive")
            with data:
                fmt = str(data["format"]) if "format" in data.files else ""
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        msg = npz_load_error(exc)
        raise ValueError(f"{os.fspath(path)}: not a readable model file ({msg})") from exc
    if fmt == _FORMAT:
        return AugmentedModel.load(path)
    return PreisachModel.load(path)
