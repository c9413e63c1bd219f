# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The model-compatibility rule: which models turn spindle sensors into wheel loads.

One predicate, :func:`spindle_layout`, for every place that applies a model to the four
spindle sensors: the live node and the offline ``predict`` / ``evaluate`` of bags.  A
model fits when

* its inputs are the 12 spindle accelerations in the package's order (``lf_ax`` ... ``rr_az``;
  ``wheel-force fit`` writes them so; a model in another order is refused rather than guessed
  at), optionally followed by all 12 spindle angular rates (``lf_wx`` ... ``rr_wz``) and then
  by the four wheel spin accelerations (``lf_spin_accel`` ... ``rr_spin_accel``, derived
  from the recorded spin rates: :mod:`.derived`) (six components, issue 33), and optionally
  last by the traction/braking split (``traction_ax``, ``braking_ax``, derived from the 12
  accelerations: :mod:`.derived`; issue 29),
* its outputs are the 12 wheel forces in that order, optionally followed by all 12 wheel
  moments (``lf_mx`` ... ``rr_mz``), never some of them,
* its units are those the messages carry: ``m/s^2`` (Imu linear acceleration), ``rad/s``
  (Imu angular velocity), ``rad/s^2`` (JointState velocity, differentiated), ``N`` (wrench
  force), ``N*m`` (wrench torque).
  Schema 1-2 files state one unit per side (``units.input``, ``units.output``); schema 3
  adds one per channel (``units.input_channels``, ``units.output_channels``).  A model
  fitted on displacement or velocity (a generic DAQ fit) would give forces off by orders of
  magnitude, so it is refused with both units named.

Everything else (a generic DAQ model, another channel set) is refused with the fault named.
"""
from dataclasses import dataclass
from typing import Optional, Tuple

from wheel_force_estimator import CORNERING_CHANNELS
from wheel_force_estimator import CORNERS
from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import MOMENT_CHANNELS
from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator import RATE_CHANNELS
from wheel_force_estimator import SPIN_ACCEL_CHANNELS
from wheel_force_estimator import SPLIT_CHANNELS
from wheel_force_estimator.core.errors import ModelFileError

__all__ = ['CHANNEL_UNITS', 'MOMENT_CHANNELS', 'SPINDLE_UNITS', 'SpindleLayout',
           'channel_units', 'declared_inputs', 'declared_outputs', 'input_sets', 'parents',
           'spindle_layout']
#: Units a spindle model must carry (the first channel group of each side).
SPINDLE_UNITS = {'input': 'm/s^2', 'output': 'N'}
#: The unit of every channel group, as the messages carry it (REP-103 SI).
GROUP_UNITS = ((INPUT_CHANNELS, 'm/s^2'), (RATE_CHANNELS, 'rad/s'),
               (SPIN_ACCEL_CHANNELS, 'rad/s^2'), (SPLIT_CHANNELS, 'm/s^2'),
               (CORNERING_CHANNELS, 'm/s^2'), (OUTPUT_CHANNELS, 'N'),
               (MOMENT_CHANNELS, 'N*m'))
#: Channel name -> unit of the messages.
CHANNEL_UNITS = {name: unit for group, unit in GROUP_UNITS for name in group}
#: Where each group comes from, for messages.
_SOURCES = {'m/s^2': 'Imu linear_acceleration', 'N': 'WrenchStamped force',
            'N*m': 'WrenchStamped torque', 'rad/s': 'Imu angular_velocity',
            'rad/s^2': 'JointState wheel velocity (differentiated)'}


def declared_inputs(rates: bool, spin: bool, split: bool = False,
                    cornering: bool = False) -> Tuple[str, ...]:
    """Return the input channels of a spindle model with or without each group of inputs."""
    return (INPUT_CHANNELS + (RATE_CHANNELS if rates else ())
            + (SPIN_ACCEL_CHANNELS if spin else ()) + (SPLIT_CHANNELS if split else ())
            + (CORNERING_CHANNELS if cornering else ()))


def _variants():
    """Return ``{declared inputs: (rates, spin, split, cornering)}`` of every spindle model."""
    flags = (False, True)
    return {declared_inputs(r, sp, sl, co): (r, sp, sl, co)
            for r in flags for sp in flags for sl in flags for co in flags}


def input_sets(input_channels) -> Tuple[Tuple[str, Tuple[int, ...]], ...]:
    """
    Return the nested input sets the fit's search tries: ``((name, columns), ...)``.

    A spindle model's inputs (:func:`declared_inputs`) give one set per group, nested in the
    order the groups are declared: ``accel``; ``accel+rates``; ``accel+rates+spin``;
    ``accel+rates+spin+split``; ``accel+rates+spin+split+cornering`` (only the groups
    present: ``accel+split`` for a model of the accelerations and the split).  When the
    model has a measured group (rates, spin) before the derived ones (the splits, functions
    of the accelerations), the derived ones are also offered on the accelerations alone:
    ``accel+split``, ``accel+split+cornering``, listed after ``accel`` (until 2026-12-07 a
    six-component row could have the cornering split only with all 12 rates and the spin;
    docs/fit_design.md, "Input sets").  Every set but ``accel`` begins with the columns of an
    earlier one (:func:`parents`), which the bordered factorisations need; the last set holds
    every input.  Any other channel list (a generic DAQ fit) is one set, ``all``, of every
    input.  ``columns`` index ``input_channels``, ascending.
    """
    names = tuple(input_channels)
    n_acc = len(INPUT_CHANNELS)
    if names[:n_acc] != INPUT_CHANNELS or names not in _variants():
        return (('all', tuple(range(len(names)))),)
    groups = []
    stop = n_acc
    for group, label in ((RATE_CHANNELS, 'rates'), (SPIN_ACCEL_CHANNELS, 'spin'),
                         (SPLIT_CHANNELS, 'split'), (CORNERING_CHANNELS, 'cornering')):
        if names[stop:stop + len(group)] == group:
            groups.append((label, tuple(range(stop, stop + len(group)))))
            stop += len(group)
    derived = [g for g in groups if g[0] in ('split', 'cornering')]
    sets = {'accel': tuple(range(n_acc))}
    for chain in (derived, groups):     # the same chain twice (no measured group): one set each
        name = 'accel'
        for label, cols in chain:
            sets[f'{name}+{label}'] = sets[name] + cols
            name = f'{name}+{label}'
    return tuple(sets.items())


def parents(sets) -> Tuple[Optional[int], ...]:
    """
    Return, per input set of :func:`input_sets`, the earlier set its columns begin with.

    The longest such set (index into ``sets``), or None (the first set): a set's
    least-squares factor is bordered from its parent's (:mod:`.nested_factor`).
    """
    out = []
    for i, (_, cols) in enumerate(sets):
        inner = [j for j in range(i) if tuple(cols[:len(sets[j][1])]) == tuple(sets[j][1])
                 and len(sets[j][1]) < len(cols)]
        out.append(max(inner, key=lambda j: len(sets[j][1])) if inner else None)
    return tuple(out)


def component_groups(output_channels) -> Tuple[Tuple[int, ...], ...]:
    """
    Return the output rows that choose their input set together: one group per component.

    A spindle model's outputs ``{corner}_{component}`` of the four corners (``lf_fy``,
    ``rf_fy``, ``lr_fy``, ``rr_fy``) are one group per component; any other output is a group
    of its own (a generic recording's channels, which search one input set anyway).  The
    derived inputs are vehicle-level signals (the four corners' mean ``ax`` and ``ay``, split
    by sign: :mod:`.derived`), so whether they carry a force component is one question for the
    four wheels, and the four rows' held-out criteria summed answer it with four rows of
    evidence instead of one (docs/fit_design.md, "Input sets").  Indices in output order.
    """
    groups = {}
    for o, name in enumerate(output_channels):
        corner, _, component = str(name).partition('_')
        key = ('component', component) if corner in CORNERS and component else ('row', o)
        groups.setdefault(key, []).append(o)
    return tuple(tuple(g) for g in groups.values())


def declared_outputs(moments: bool) -> Tuple[str, ...]:
    """Return the output channels of a spindle model with or without the moments."""
    return OUTPUT_CHANNELS + (MOMENT_CHANNELS if moments else ())


def channel_units(model) -> Tuple[Tuple[str, ...], Tuple[str, ...]]:
    """
    Return the declared unit of every input and output channel of ``model``.

    Schema 3 files list them (``units.input_channels`` / ``units.output_channels``).  A
    file with one unit per side states the unit of its first group (accelerations, forces);
    its other spindle groups (rates and spin, moments: schema 2 already allowed moments) are
    read in the units of the messages when that first unit is the messages' own, since
    nothing else could have been meant; any other channel shares its side's unit.
    """
    units = dict(model.units)

    def side(names, key, first_group):
        listed = units.get(f'{key}_channels')
        if listed:
            return tuple(listed)
        unit = units.get(key)
        primary = CHANNEL_UNITS.get(first_group[0])
        return tuple(CHANNEL_UNITS[n] if unit == primary and n in CHANNEL_UNITS else unit
                     for n in names)
    return (side(model.input_channels, 'input', INPUT_CHANNELS),
            side(model.output_channels, 'output', OUTPUT_CHANNELS))


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
    rates, spin : bool
        The model's inputs include the spindle angular rates / the wheel spin rates.
    derived : tuple of str
        The model's last inputs that the caller derives from the accelerations (the
        traction/braking and cornering splits, :mod:`.derived`); no topic or bag group
        carries them.

    """

    force_rows: Tuple[Tuple[int, int, int], ...]
    torque_rows: Optional[Tuple[Tuple[int, int, int], ...]]
    rates: bool = False
    spin: bool = False
    derived: Tuple[str, ...] = ()

    @property
    def extras(self) -> Tuple[str, ...]:
        """Return the six-component groups a bag must carry for this model (reader names)."""
        return tuple(name for name, needed in (('moments', self.torque_rows is not None),
                                               ('rates', self.rates), ('spin', self.spin))
                     if needed)


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
    variants = _variants()
    if inputs not in variants:
        raise ModelFileError(
            f'{where}: model inputs {list(inputs)} are not the spindle accelerations '
            f'{INPUT_CHANNELS[0]} ... {INPUT_CHANNELS[-1]} (optionally followed by all of the '
            f'angular rates {RATE_CHANNELS[0]} ... {RATE_CHANNELS[-1]}, then the spin rates '
            f'{SPIN_ACCEL_CHANNELS[0]} ... {SPIN_ACCEL_CHANNELS[-1]}, then the split '
            f'{SPLIT_CHANNELS[0]}, {SPLIT_CHANNELS[1]}, then the cornering split '
            f'{CORNERING_CHANNELS[0]}, {CORNERING_CHANNELS[1]}) in that order; a model '
            f'fitted on generic recordings is applied to them with --input, --output and --fs')
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
    in_units, out_units = channel_units(model)
    for names, declared in ((inputs, in_units), (outputs, out_units)):
        if len(declared) != len(names):
            raise ModelFileError(f'{where}: model units list {len(declared)} units for '
                                 f'{len(names)} channels')
        for name, unit in zip(names, declared):
            if unit != CHANNEL_UNITS[name]:
                source = _SOURCES.get(CHANNEL_UNITS[name], 'the recorded rate')
                raise ModelFileError(
                    f"{where}: model unit of {name} is {unit!r} but the bag's {source} is in "
                    f'{CHANNEL_UNITS[name]!r}; nothing is converted')
    n = len(OUTPUT_CHANNELS)
    force_rows = tuple(tuple(range(3 * c, 3 * c + 3)) for c in range(len(CORNERS)))
    torque_rows = None if len(outputs) == n else tuple(
        tuple(range(n + 3 * c, n + 3 * c + 3)) for c in range(len(CORNERS)))
    rates, spin, split, cornering = variants[inputs]
    derived = declared_inputs(False, False, split, cornering)[len(INPUT_CHANNELS):]
    return SpindleLayout(force_rows, torque_rows, rates, spin, derived)
