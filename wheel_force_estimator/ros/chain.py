# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The live node's estimation chain for one model file: loaded, checked, built and warmed up.

Shared by ``configure`` and ``~/reload_model`` (:mod:`.node`): a model is accepted only when
its whole chain can be built and has run once, so a reload that fails keeps the old model
running.
"""
import dataclasses
from typing import Tuple

import numpy as np

from wheel_force_estimator import CORNERS
from wheel_force_estimator.bagio.cdr import decode_imu
from wheel_force_estimator.bagio.cdr import encode_imu
from wheel_force_estimator.bagio.cdr import encode_wrench
from wheel_force_estimator.core.model import FrfModel
from wheel_force_estimator.core.model import load_model
from wheel_force_estimator.core.predict import Predictor
from wheel_force_estimator.ros.params import model_layout
from wheel_force_estimator.ros.params import ModelLayout
from wheel_force_estimator.ros.params import NodeParams
from wheel_force_estimator.ros.stream import ForceStream


def load_chain(params: NodeParams, model_path: str
               ) -> Tuple[FrfModel, ModelLayout, ForceStream]:
    """
    Return (model, layout, stream) for the model file ``model_path``, run once.

    Raises
    ------
    WheelForceError
        The file is not a usable model, or does not fit the node's parameters (named).

    """
    params = dataclasses.replace(params, model_path=model_path)
    model = load_model(model_path)
    layout = model_layout(model, params)
    stream = make_stream(model, layout, params)
    warm_up(model, layout, params)
    return model, layout, stream


def make_stream(model, layout, params) -> ForceStream:
    """Return the node's estimation stream: the one place its Predictor is made."""
    # The live (causal) estimator for this look-ahead (the model's, else the cut FIR).
    predictor = Predictor(model, causal_delay_samples=layout.causal_delay_samples)
    # the rows fed: the model's inputs but the splits, which the stream derives from the
    # accelerations
    n_fed = predictor.n_inputs - len(layout.derived)
    # the model's spin inputs, last fed, arrive as spin rates: the stream differentiates them
    spin_rows = range(n_fed - len(CORNERS), n_fed) if layout.spin else ()
    return ForceStream(predictor, params.block_size, params.sn_slope,
                       damage_period_s=params.damage_publish_period_s,
                       sn_slope_moment=params.sn_slope_moment, spin_rows=spin_rows,
                       derived=layout.derived)


def warm_up(model, layout, params):
    """
    Run the whole processing chain once on made-up samples, on throwaway objects.

    The first call of the filter, the damage counter (numba) and the codecs compiles and plans
    (~0.2 s measured, more on a loaded machine); done while the first messages arrive, it
    stalls the executor long enough to overflow the input queues.
    """
    n = 2 * params.block_size + layout.causal_delay_samples
    period_ns = int(round(1e9 / model.fs_hz))
    stamps = np.arange(1, n + 1, dtype=np.int64) * period_ns
    n_fed = len(model.input_channels) - len(layout.derived)
    accel = np.repeat(np.asarray(model.static_accel_mps2, float)[:n_fed, None], n, axis=1)
    blobs = [raw for c in range(len(CORNERS))
             for raw in encode_imu(stamps, accel[3 * c:3 * c + 3], 'warm_up')]
    decode_imu(blobs)
    stream = make_stream(model, layout, params)     # a throwaway twin of the node's
    stream.feed(stamps, accel)
    stream.flush()
    out_stamps, force = stream.take()
    encode_wrench(out_stamps, force[list(layout.force_rows[0])], 'warm_up')
    stream.final_damage_report()
