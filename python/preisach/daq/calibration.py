"""Linear calibrations of the DAQ interface of the SS15 (thesis Appendix B).

Two calibrations appear in the thesis:

* **Quanser ADC** (Table B.1): a DC supply of -5 ... +5 V, measured with a multimeter, is read on
  ADC channels Ch0-Ch3 (10-sample moving average at 1 ms).  The reading is essentially the
  identity (gain 0.997-0.998, offset about 5 mV); no equation is printed.
* **Quanser DAC + SA11 amplifier** (Table B.2): the DAC voltage ``V_a,bin`` (CH 0 drives
  amplifier channel A, CH 1 drives channel B, both set to the same value) against the
  amplifier's high-voltage outputs ``V_aout`` and ``V_bout``.  Matlab ``polyfit`` of degree 1
  gives Eq. (B.1a) for channel A and Eq. (B.1b) for channel B::

      V_aout = -14.16 * V_ain - 0.12      (B.1a)  -> SS15_CHANNEL_A
      V_bout = -14.12 * V_bin - 0.02      (B.1b)  -> SS15_CHANNEL_B

  with RMS residuals 0.20 V and 0.19 V.  The Flexmorph studied in the thesis is driven by
  channel B (Eq. B.2: ``V_in = -14.12 * V_bin - 0.02``).

A :class:`LinearCalibration` maps *connector* volts ``x`` (what the DAQ card sets or reads)
to *physical* volts ``y = gain * x + offset`` (what is really applied or measured); its
:meth:`~LinearCalibration.inverse` gives the connector voltage needed for a physical one.

Reproducing Eq. (B.1a)/(B.1b).  Table B.2 is printed as two side-by-side blocks of 11 rows
(inputs 0 ... 10 V and -10 ... 0 V), so the 0 V row appears twice with identical readings.
A least-squares line through **all 22 rows, duplicate 0 V row included**, reproduces the printed
equations and RMS residuals to the printed precision:

========  ==========  ==========  ============  ============
channel   gain        offset (V)  RMS res. (V)  max res. (V)
========  ==========  ==========  ============  ============
A         -14.156519  -0.116818   0.1985        0.360
B         -14.121883  -0.024091   0.1878        0.342
========  ==========  ==========  ============  ============

Dropping the duplicate row (21 distinct points) keeps the gains but moves the offsets to
-0.101 V and -0.009 V and the RMS residuals to 0.189 V and 0.179 V, which do not round to the
printed -0.12/-0.02 and 0.20 V, so the thesis evidently fitted all 22 rows.

The 0.2 V residual is not measurement noise: each half of the table is linear to about 6 mV
RMS on its own, but the two halves have different offsets (for channel A about -0.46 V for
inputs 0 ... 10 V against about +0.30 V for inputs -10 ... -1 V, and slightly different
slopes), i.e. the amplifier has a polarity-dependent offset of roughly 0.7-0.8 V, which a single
line splits into a systematic, V-shaped residual.  Treat the constants below as a +/-0.4 V
description of the amplifier, as the thesis did.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any, Union

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "AdcTable",
    "AmplifierTable",
    "LinearCalibration",
    "SS15_CHANNEL_A",
    "SS15_CHANNEL_B",
    "SS15_INPUT_GAIN",
    "TABLE_B1",
    "TABLE_B2",
    "fit_linear_calibration",
]

_FloatOrArray = Union[float, NDArray[np.float64]]


def _finite_real(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a real number, got {type(value).__name__}")
    number = float(value)
    if not math.isfinite(number):
        raise ValueError(f"{name} must be finite, got {number!r}")
    return number


@dataclass(frozen=True)
class LinearCalibration:
    """Affine map from connector volts to physical volts, ``y = gain * x + offset``.

    Parameters
    ----------
    gain : float
        Slope (V/V); must be finite and non-zero so that the map is invertible.
    offset : float
        Intercept (V), the physical voltage at 0 V on the connector.
    rms_residual : float, default nan
        Root-mean-square residual ``sqrt(mean((y - fit)**2))`` of the fit (V); ``nan`` if
        unknown.
    max_residual : float, default nan
        Largest absolute residual of the fit (V); ``nan`` if unknown.
    n_points : int, default 0
        Number of calibration points the fit used (0 if unknown).

    Examples
    --------
    >>> cal = LinearCalibration(gain=-14.12, offset=-0.02)
    >>> round(cal(1.0), 6)
    -14.14
    >>> round(cal.inverse(-14.14), 6)
    1.0

    """

    gain: float
    offset: float
    rms_residual: float = math.nan
    max_residual: float = math.nan
    n_points: int = 0

    def __post_init__(self) -> None:
        gain = _finite_real("gain", self.gain)
        if gain == 0.0:
            raise ValueError("gain must be non-zero (the calibration must be invertible)")
        offset = _finite_real("offset", self.offset)
        residuals = {}
        for name in ("rms_residual", "max_residual"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, numbers.Real):
                raise TypeError(f"{name} must be a real number, got {type(value).__name__}")
            value = float(value)
            if not (math.isnan(value) or (math.isfinite(value) and value >= 0.0)):
                raise ValueError(f"{name} must be >= 0 and finite, or nan; got {value!r}")
            residuals[name] = value
        n_points = self.n_points
        if isinstance(n_points, bool) or not isinstance(n_points, numbers.Integral):
            raise TypeError(f"n_points must be an int, got {type(n_points).__name__}")
        if n_points < 0:
            raise ValueError(f"n_points must be >= 0, got {n_points}")
        object.__setattr__(self, "gain", gain)
        object.__setattr__(self, "offset", offset)
        object.__setattr__(self, "rms_residual", residuals["rms_residual"])
        object.__setattr__(self, "max_residual", residuals["max_residual"])
        object.__setattr__(self, "n_points", int(n_points))

    def __call__(self, x: ArrayLike) -> _FloatOrArray:
        """Map connector volts ``x`` to physical volts ``gain * x + offset``.

        Parameters
        ----------
        x : float or array_like
            Connector voltage(s) (V).

        Returns
        -------
        float or numpy.ndarray
            Physical voltage(s) (V); a ``float`` for scalar input.

        """
        y = self.gain * np.asarray(x, dtype=np.float64) + self.offset
        return float(y) if y.ndim == 0 else y

    def inverse(self, y: ArrayLike) -> _FloatOrArray:
        """Map physical volts ``y`` back to connector volts ``(y - offset) / gain``.

        Parameters
        ----------
        y : float or array_like
            Physical voltage(s) (V), e.g. the desired amplifier output.

        Returns
        -------
        float or numpy.ndarray
            Connector voltage(s) (V); a ``float`` for scalar input.

        """
        x = (np.asarray(y, dtype=np.float64) - self.offset) / self.gain
        return float(x) if x.ndim == 0 else x

    def to_dict(self) -> dict[str, Any]:
        """Return the fields as a plain ``dict`` (floats and an int)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> LinearCalibration:
        """Build a calibration from a mapping such as the output of :meth:`to_dict`.

        ``gain`` and ``offset`` are required; the residual fields are optional.

        Raises
        ------
        ValueError
            If a required key is missing or an unknown key is present.

        """
        names = {f.name for f in fields(cls)}
        unknown = set(data) - names
        if unknown:
            raise ValueError(f"unknown LinearCalibration field(s): {sorted(unknown)}")
        missing = {"gain", "offset"} - set(data)
        if missing:
            raise ValueError(f"missing LinearCalibration field(s): {sorted(missing)}")
        return cls(**dict(data))


def fit_linear_calibration(x: ArrayLike, y: ArrayLike) -> LinearCalibration:
    """Least-squares straight line ``y = gain * x + offset`` through calibration points.

    Equivalent to Matlab's ``polyfit(x, y, 1)`` (and :func:`numpy.polyfit`), computed from
    centred sums so it is well conditioned and emits no warnings.

    Parameters
    ----------
    x : array_like
        Connector voltages (V), 1-D.
    y : array_like
        Corresponding physical voltages (V), 1-D, same length as ``x``.

    Returns
    -------
    LinearCalibration
        With ``rms_residual = sqrt(mean(r**2))`` and ``max_residual = max(abs(r))`` of the
        residuals ``r = y - (gain * x + offset)`` (V), and ``n_points = len(x)``.

    Raises
    ------
    ValueError
        If ``x`` or ``y`` is not 1-D, their lengths differ, there are fewer than 2 points,
        any value is NaN or infinite, all ``x`` are equal, or all ``y`` are equal (zero gain).

    Examples
    --------
    >>> cal = fit_linear_calibration([0, 1, 2], [1.0, 3.0, 5.0])
    >>> cal.gain, cal.offset
    (2.0, 1.0)

    """
    xa = np.asarray(x, dtype=np.float64)
    ya = np.asarray(y, dtype=np.float64)
    for name, arr in (("x", xa), ("y", ya)):
        if arr.ndim != 1:
            raise ValueError(f"{name} must be 1-D, got shape {arr.shape}")
    if xa.shape != ya.shape:
        raise ValueError(f"x and y must have the same length, got {xa.size} and {ya.size}")
    if xa.size < 2:
        raise ValueError(f"at least 2 calibration points are needed, got {xa.size}")
    for name, arr in (("x", xa), ("y", ya)):
        bad = ~np.isfinite(arr)
        if bad.any():
            raise ValueError(
                f"{name} contains NaN or infinite values at index {np.flatnonzero(bad).tolist()}"
            )
    xm = float(xa.mean())
    ym = float(ya.mean())
    dx = xa - xm
    sxx = float(dx @ dx)
    if sxx == 0.0:
        raise ValueError("all x values are equal; a line cannot be fitted")
    gain = float(dx @ (ya - ym)) / sxx
    if gain == 0.0:
        raise ValueError("the fitted gain is zero (y does not depend on x); not invertible")
    offset = ym - gain * xm
    residuals = ya - (gain * xa + offset)
    return LinearCalibration(
        gain=gain,
        offset=offset,
        rms_residual=float(np.sqrt(np.mean(residuals**2))),
        max_residual=float(np.max(np.abs(residuals))),
        n_points=int(xa.size),
    )


def _frozen(values: list[float]) -> NDArray[np.float64]:
    arr = np.array(values, dtype=np.float64)
    arr.flags.writeable = False
    return arr


@dataclass(frozen=True, eq=False)
class AmplifierTable:
    """Table B.2: DAC voltage against SA11 amplifier output voltages.

    The printed table has two side-by-side blocks of 11 rows; the arrays list the left block
    (inputs 0 ... 10 V) then the right block (inputs -10 ... 0 V), in printed row order, so the
    0 V row appears twice (indices 0 and 21).  Arrays are read-only.

    Attributes
    ----------
    v_in : numpy.ndarray
        ``V_a,bin``, the DAC voltage set on both CH 0 and CH 1 (V).
    v_a_out : numpy.ndarray
        ``V_aout``, amplifier channel A output (V), driven by CH 0.
    v_b_out : numpy.ndarray
        ``V_bout``, amplifier channel B output (V), driven by CH 1.

    """

    v_in: NDArray[np.float64]
    v_a_out: NDArray[np.float64]
    v_b_out: NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class AdcTable:
    """Table B.1: DC supply voltage against Quanser ADC readings (all in V).

    Attributes
    ----------
    supply : numpy.ndarray
        DC power-supply voltage measured with the multimeter (V).
    ch0, ch1, ch2, ch3 : numpy.ndarray
        Voltage read on ADC channels 0-3 (V).  For an ADC calibration the reading is the
        connector voltage ``x`` and the supply is the physical voltage ``y``.

    """

    supply: NDArray[np.float64]
    ch0: NDArray[np.float64]
    ch1: NDArray[np.float64]
    ch2: NDArray[np.float64]
    ch3: NDArray[np.float64]


TABLE_B2 = AmplifierTable(
    v_in=_frozen([0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, -10, -9, -8, -7, -6, -5, -4, -3, -2, -1, 0]),
    v_a_out=_frozen(
        [
            -0.45,
            -14.56,
            -28.66,
            -42.77,
            -56.88,
            -70.97,
            -85.08,
            -99.18,
            -113.29,
            -127.39,
            -141.48,
            141.30,
            127.22,
            113.12,
            99.01,
            84.91,
            70.81,
            56.71,
            42.61,
            28.50,
            14.40,
            -0.45,
        ]
    ),  # fmt: skip
    v_b_out=_frozen(
        [
            -0.34,
            -14.42,
            -28.48,
            -42.57,
            -56.64,
            -70.70,
            -84.78,
            -98.84,
            -112.93,
            -126.99,
            -141.05,
            141.06,
            127.00,
            112.94,
            98.86,
            84.79,
            70.72,
            56.65,
            42.59,
            28.50,
            14.44,
            -0.34,
        ]
    ),  # fmt: skip
)
"""Raw data of thesis Table B.2 (V); see :class:`AmplifierTable`."""

TABLE_B1 = AdcTable(
    supply=_frozen([-5.00, -4.00, -3.00, -2.00, -1.00, 0.00, 1.00, 2.00, 3.00, 4.00, 5.00]),
    ch0=_frozen([-5.00, -4.02, -3.02, -2.02, -1.01, 0.00, 1.00, 2.00, 3.00, 4.01, 5.00]),
    ch1=_frozen([-5.00, -4.03, -3.02, -2.02, -1.01, 0.00, 1.00, 2.00, 3.00, 4.02, 5.00]),
    ch2=_frozen([-5.00, -4.03, -3.02, -2.02, -1.01, 0.00, 1.00, 2.00, 3.01, 4.02, 5.00]),
    ch3=_frozen([-5.00, -4.03, -3.02, -2.02, -1.01, 0.00, 1.00, 2.00, 3.01, 4.00, 5.00]),
)
"""Raw data of thesis Table B.1 (V); see :class:`AdcTable`."""

SS15_CHANNEL_A = LinearCalibration(
    gain=-14.16, offset=-0.12, rms_residual=0.20, max_residual=0.36, n_points=22
)
"""Eq. (B.1a): SA11 channel A output (V) from Quanser DAC CH 0 (V).

``gain``, ``offset`` and ``rms_residual`` are the thesis's printed values; ``max_residual``
(not printed) is that of the least-squares fit to all 22 rows of :data:`TABLE_B2`, rounded.
"""

SS15_CHANNEL_B = LinearCalibration(
    gain=-14.12, offset=-0.02, rms_residual=0.19, max_residual=0.34, n_points=22
)
"""Eq. (B.1b) = Eq. (B.2): SA11 channel B output (V) from Quanser DAC CH 1 (V).

This channel drives the Flexmorph studied in the thesis.  ``gain``, ``offset`` and
``rms_residual`` are the thesis's printed values; ``max_residual`` (not printed) is that of the
least-squares fit to all 22 rows of :data:`TABLE_B2`, rounded.
"""

SS15_INPUT_GAIN: float = abs(SS15_CHANNEL_B.gain)
"""Actuator volts per DAQ volt of the SS15 drive (``|gain|`` of Eq B.2, 14.12 V/V).

The thesis states the noise amplitude and the PI gains in DAQ volts; the experiments and trial
files multiply them by this gain before they reach the model input.
"""
