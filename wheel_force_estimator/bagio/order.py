# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The order of a topic's samples: ``header.stamp``, whatever order the bag stores them in.

A bag stores messages in receive (bag-time) order.  Delivery reorders them (several DDS
writers or readers, recorder threads and caches, a logger flushing per channel), so a message
may be stored after one stamped later; its place is given by its stamp.  What delivery cannot
do is move a message back by more than it is ever late: a recorder's queues hold milliseconds
to a few hundred milliseconds of data, while a looped replay, a restarted logger clock or two
recordings concatenated jump back by the length of what they repeat.  The rule:

* a message stamped earlier than an earlier-stored one by at most ``MAX_REORDER_NS`` (1 s)
  is a late delivery: it is moved to its stamp's place and counted (``n_reordered``);
* a jump back of more than ``MAX_REORDER_NS`` is an error naming the message and both stamps;
* two messages with the same stamp are an error (a repeated sample, never delivery).

A loop shorter than 1 s repeats its stamps, so the duplicate rule refuses it.
"""
from typing import Tuple

import numpy as np

from wheel_force_estimator.bagio.align import stamp_text
from wheel_force_estimator.core.errors import BagError

#: Largest backwards step (stamp earlier than the latest stamp stored before it) taken as
#: delivery reordering [ns]; see the module docstring for why 1 s.
MAX_REORDER_NS = 1_000_000_000


def order_by_stamp(path, topic: str, stamp_ns: np.ndarray,
                   values: np.ndarray) -> Tuple[np.ndarray, np.ndarray, int]:
    """
    Sort one topic's samples by stamp; refuse duplicates and jumps back beyond delivery.

    Parameters
    ----------
    path : str or pathlib.Path
        Recording, for messages.
    topic : str
        Topic name, for messages.
    stamp_ns : numpy.ndarray, shape (n,), int64
        ``header.stamp`` in bag (storage) order.
    values : numpy.ndarray, shape (n, k)
        Values of each message, same order.

    Returns
    -------
    stamp_ns : numpy.ndarray, shape (n,), int64
        Strictly increasing stamps (the input array itself if already in order).
    values : numpy.ndarray, shape (n, k)
        Values in stamp order (the input array itself if already in order).
    n_reordered : int
        Messages stored after a later-stamped one (late deliveries moved into place).

    Raises
    ------
    BagError
        A jump back of more than ``MAX_REORDER_NS`` (message in bag order and both stamps
        named) or a duplicate stamp (both messages named).

    """
    stamp = np.asarray(stamp_ns)
    if stamp.size < 2:
        return stamp, values, 0
    step = np.diff(stamp)
    if (step > 0).all():
        return stamp, values, 0
    latest = np.maximum.accumulate(stamp)[:-1]
    back = latest - stamp[1:]  # > 0: stored after a message stamped later
    far = np.flatnonzero(back > MAX_REORDER_NS)
    if far.size:
        i = int(far[0]) + 1
        raise BagError(
            f'{path}: {topic}: stamp goes backwards at message {i} (bag order) by '
            f'{back[i - 1] / 1e9:.3f} s: {stamp_text(stamp[i])} after {stamp_text(latest[i - 1])}'
            f'; more than delivery reorders ({MAX_REORDER_NS / 1e9:g} s): a looped, restarted '
            'or concatenated recording')
    order = np.argsort(stamp, kind='stable')
    ordered = stamp[order]
    same = np.flatnonzero(np.diff(ordered) == 0)
    if same.size:
        a, b = sorted((int(order[same[0]]), int(order[same[0] + 1])))
        raise BagError(f'{path}: {topic}: duplicate stamp at message {b} (bag order): '
                       f'{stamp_text(stamp[b])} as message {a}')
    return ordered, values[order], int(np.count_nonzero(back > 0))
