# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
What modelling a concealed effect could gain at most: the plain fit with and without it.

For each effect of the simulator part of ``bench/diagnose_blind.py`` (same car, seed, sizes
and record lengths: 2-minute training, 5-minute holdout at ``seed + 100``), a plain
``wheel-force fit`` (``fit``'s design, :func:`diagnosis.run.real_linear_fit`) is fitted on the
car with the effect and, as the baseline in the same run, on the same roads without it; each
is judged on the holdout of its own car.  No term can take the error below the effect-free
figure, so ``1 - without / with`` bounds what any model of the effect can gain over the plain
fit.  Printed per effect, for the four channels the effect changes most: the effect's force
(the difference of the two cars' targets on the holdout, mean removed) as % of the channel's
RMS, both fits' RMSE % (unfiltered / 1 Hz high-passed) and the bound.

Run: ``python bench/diagnose_bound.py [--seed 5] [--effects damper_asymmetry,...]``
(~2 min per effect on a 2-core machine).
"""
import argparse
from pathlib import Path
import sys

import numpy as np

from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator.diagnosis.run import real_linear_fit
from wheel_force_estimator.sim.api import simulate

sys.path.insert(0, str(Path(__file__).resolve().parent))
import diagnose_blind as blind  # noqa: E402,I100

NONLINEAR = ('damper_asymmetry', 'sensor_saturation', 'rebound_stop', 'cubic_stiffness',
             'coulomb_friction')


def plain_fit_figures(physics, params, seed: int):
    """Return (unfiltered %, 1 Hz HP %, holdout targets) of the plain fit of one car."""
    real = [blind._rec(simulate('proving_ground', physics, seed, 0.2, vehicle=blind.CAR,
                                effect_params=params), 'real')]
    hold = [blind._rec(simulate('proving_ground', physics, seed + 100, 0.5, vehicle=blind.CAR,
                                effect_params=params), 'holdout')]
    raw, hp = blind.holdout_figures(real_linear_fit(real, blind.BAG_CONFIG).model, hold)
    return raw, hp, np.asarray(hold[0].outputs)


def main() -> int:
    """Print the bound per effect."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--seed', type=int, default=5)
    parser.add_argument('--effects', default=','.join(NONLINEAR))
    args = parser.parse_args()
    base_raw, base_hp, base_y = plain_fit_figures((), None, args.seed)
    print(f'seed {args.seed}; per channel: effect % of RMS | plain fit with the effect '
          f'(unf / hp) | without it | bound on the gain (unf / hp)')
    for effect in args.effects.split(','):
        params, factor = blind.draw_params(effect, args.seed, 'concealed')
        raw, hp, y = plain_fit_figures(blind.simulated_physics(effect), params, args.seed)
        d = y - base_y
        size = (np.sqrt(np.mean((d - d.mean(axis=1, keepdims=True)) ** 2, axis=1))
                / np.std(y, axis=1) * 100.0)
        print(f'{effect} (size x{factor:.2f})')
        for o in np.argsort(-size)[:4]:
            print(f'  {OUTPUT_CHANNELS[o]:6s} {size[o]:5.1f} | {raw[o]:5.1f} / {hp[o]:5.1f} | '
                  f'{base_raw[o]:5.1f} / {base_hp[o]:5.1f} | '
                  f'{100 * (1 - base_raw[o] / raw[o]):5.1f} / '
                  f'{100 * (1 - base_hp[o] / hp[o]):5.1f} %', flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
