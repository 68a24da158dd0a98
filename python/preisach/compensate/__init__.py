"""Inverse Preisach model and feedforward compensation.

* :func:`invert` (also :meth:`preisach.PreisachModel.inverse`) — the exact inverse of a model:
  the input (V) that makes the model's output follow a reference (V), from a given state;
* :func:`inverter` (also :meth:`preisach.PreisachModel.inverter`) — the same, target by
  target, for a real-time loop;
* :mod:`preisach.compensate.augmented` — inverses of the physics blocks that diagnosis adds
  around the hysteresis (delay, linear dynamics), for compensating with an augmented model;
* :mod:`preisach.compensate.rate` — the inverse of the rate-dependent model (bracket on the
  grid, then regula falsi: the rate makes it non-polynomial);
* :mod:`preisach.compensate.trial` — the ``track`` step of scripted trials;
* :mod:`preisach.compensate.tracking` — the tracking experiment (uncompensated, feedforward,
  PI, PI + feedforward) on a model or a device.

Layer: uses the model and the C++ core only; the experiments and the CLI build on it.
"""

from __future__ import annotations

from .inverse import InverseResult, invert, inverter

__all__ = ["InverseResult", "invert", "inverter"]
