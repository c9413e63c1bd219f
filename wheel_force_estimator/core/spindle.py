# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The model-compatibility rule: which models turn spindle accelerations into wheel loads.

One predicate, :func:`spindle_layout`, for every place that applies a model to the four
spindle accelerometers: the live node and the offline ``predict`` / ``evaluate`` of bags.  A
model fits when

* its inputs are the 12 spindle accelerations in the package's order (``lf_ax`` ... ``rr_az``;
  ``wheel-force fit`` writes them so; a model in another order is refused rather than guessed
  at),
* its outputs are the 12 wheel forces in that order, optionally followed by all 12 wheel
  moments (``lf_mx`` ... ``rr_mz``), never some of them,
* its units are ``m/s^2`` in and ``N`` out: Imu messages carry m/s²; a model fitted on
  displacement or velocity (a generic DAQ fit) would give forces off by orders of magnitude.

Everything else (a generic DAQ model, another channel set) is refused with the fault named.
"""
from dataclasses import dataclass
from typing import Optional, Tuple

from wheel_force_estimator import CORNERS
from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator.core.errors import ModelFileError

#: Wheel moments a model may add after the forces (published as the wrench torque).
MOMENT_CHANNELS = tuple(f'{c}_m{ax}' for c in CORNERS for ax in 'xyz')
#: Units a spindle model must carry.
SPINDLE_UNITS = {'input': 'm/s^2', 'output': 'N'}


@dataclass(frozen=True)
class SpindleLayout:
    """
    Where each corner's loads are in a fitting model's output.

    Attributes
    ----------
    force_rows : tuple of tuple of int
        Per corner (lf, rf, lr, rr), the output rows of force x, y, z.
    torque_rows : tuple of tuple of int or None
        Per corner, the rows of moment x, y, z; ``None`` when the model has no moments.

    """

    force_rows: Tuple[Tuple[int, int, int], ...]
    torque_rows: Optional[Tuple[Tuple[int, int, int], ...]]


def spindle_layout(model, where: str) -> SpindleLayout:
    """
    Check that ``model`` maps the spindle accelerations to wheel loads (see module notes).

    Parameters
    ----------
    model : FrfModel
        The loaded model.
    where : str
        How to name the model in a message (its path).

    Returns
    -------
    SpindleLayout

    Raises
    ------
    ModelFileError
        Channels or units that do not fit, with what was found and what is needed.

    """
    inputs = tuple(model.input_channels)
    outputs = tuple(model.output_channels)
    if inputs != INPUT_CHANNELS:
        raise ModelFileError(
            f'{where}: model inputs {list(inputs)} are not the spindle accelerations '
            f'{INPUT_CHANNELS[0]} ... {INPUT_CHANNELS[-1]} in that order; a model fitted on '
            f'generic recordings is applied to them with --input, --output and --fs')
    if outputs not in (OUTPUT_CHANNELS, OUTPUT_CHANNELS + MOMENT_CHANNELS):
        raise ModelFileError(
            f'{where}: model outputs {list(outputs)} are not the wheel forces '
            f'{OUTPUT_CHANNELS[0]} ... {OUTPUT_CHANNELS[-1]} (optionally followed by all of '
            f'the moments {MOMENT_CHANNELS[0]} ... {MOMENT_CHANNELS[-1]}) in that order')
    units = dict(model.units)
    if any(units.get(k) != v for k, v in SPINDLE_UNITS.items()):
        raise ModelFileError(
            f'{where}: model units {units}: spindle Imu messages carry linear accelerations '
            f"in m/s^2 and the loads are in N; a model with units input 'm/s^2', output 'N' "
            f'is needed')
    n = len(OUTPUT_CHANNELS)
    force_rows = tuple(tuple(range(3 * c, 3 * c + 3)) for c in range(len(CORNERS)))
    torque_rows = None if len(outputs) == n else tuple(
        tuple(range(n + 3 * c, n + 3 * c + 3)) for c in range(len(CORNERS)))
    return SpindleLayout(force_rows, torque_rows)
