# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Payload rows of Imu/WrenchStamped messages in bulk, for the tests of the bulk decoder."""
from typing import Callable

import numpy as np

from wheel_force_estimator.bagio.cdr import body_offset
from wheel_force_estimator.bagio.cdr import Layout
from wheel_force_estimator.bagio.cdr import payload_length
from wheel_force_estimator.core.errors import BagError

NS_PER_S = 1_000_000_000


def record_dtype(layout: Layout, strlen: int) -> np.dtype:
    """Return the structured dtype of one payload row: stamp fields and the three values."""
    values_at = body_offset(strlen) + layout.value_offset
    return np.dtype({
        'names': ['enc', 'sec', 'nsec', 'values'],
        'formats': ['>u2', '<i4', '<u4', ('<f8', (3,))],
        'offsets': [0, 4, 8, values_at],
        'itemsize': payload_length(layout, strlen),
    })


def encode_rows(layout: Layout, stamp_ns: np.ndarray, values: np.ndarray,
                make_msg: Callable, serialize: Callable[[object], bytes]) -> np.ndarray:
    """
    Serialise n messages of one topic in bulk (test rows checked against rosbags).

    Parameters
    ----------
    layout : Layout
        Message layout.
    stamp_ns : numpy.ndarray, shape (n,), int64
        Header stamps (>= 0).
    values : numpy.ndarray, shape (n, 3), float64
        x, y, z values.
    make_msg : callable
        ``make_msg(stamp_ns, (x, y, z)) -> message`` building the full message (constant
        fields such as frame_id and covariances included).
    serialize : callable
        Generic serialiser ``serialize(msg) -> bytes``; defines the byte template and checks
        the first and last rows.

    Returns
    -------
    numpy.ndarray, shape (n, L), uint8
        One payload per row.

    Raises
    ------
    BagError
        The bulk encoding disagrees with the generic serialiser (unexpected layout).

    """
    n = len(stamp_ns)
    template = np.frombuffer(bytes(serialize(make_msg(0, (0.0, 0.0, 0.0)))), np.uint8)
    strlen = int(template[12:16].view('<u4')[0])
    if len(template) != payload_length(layout, strlen):
        raise BagError(f'{layout.msgtype}: unexpected serialised length {len(template)}')
    rows = np.tile(template, (n, 1))
    rec = rows.view(record_dtype(layout, strlen))[:, 0]
    rec['sec'] = stamp_ns // NS_PER_S
    rec['nsec'] = stamp_ns % NS_PER_S
    rec['values'] = values
    for i in {0, n - 1} if n else ():
        ref = bytes(serialize(make_msg(int(stamp_ns[i]), tuple(values[i]))))
        if ref != rows[i].tobytes():
            raise BagError(f'{layout.msgtype}: bulk CDR encoding differs from rosbags at row {i}')
    return rows
