# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The one acceptance rule of a candidate measured by its held-out gain.

Every finder that scores a candidate by the fraction of the residual it removes on held-out
time blocks accepts it through :func:`rejection`: the per-channel selection and the pooled
fits over an axis (:class:`selection.Selector`), the search inside a structure
(:mod:`finders.structure`), the pooled kind of hardening (:mod:`finders.hardening`) and the
pooled spring-rate omission (:mod:`finders.structural`).  The finders that compare FRFs or
the recorded motion (left-right coupling, mass omission, clipped sensor, tyre lift-off) name
an effect by a significance test at their own false-alarm level instead.
"""
from typing import Optional


def rejection(rules, gain: float, null: Optional[float] = None,
              drop_pct: Optional[float] = None,
              min_gain: Optional[float] = None) -> Optional[str]:
    """
    Return why a candidate is not accepted, or None.

    Parameters
    ----------
    rules : SelectionConfig
        ``min_gain``, ``null_factor`` and ``min_improvement_pct``.
    gain : float
        Fraction of the residual the candidate explains on held-out blocks.
    null : float, optional
        Best fraction the same candidate explains with time-shifted features.
    drop_pct : float, optional
        How much it lowers the cross-validated RMSE [points of %].
    min_gain : float, optional
        The gain required instead of ``rules.min_gain`` (a pooled fit that must beat a
        rival's gain by a factor).

    Returns
    -------
    str or None
        The reason, or None when accepted.  A figure not known yet (None) is not judged, so a
        caller may reject on the gain before paying for the null.

    """
    floor = rules.min_gain if min_gain is None else min_gain
    if gain < floor:
        return f'explains {gain:.1%} < {floor:.0%} of the residual'
    if null is not None and gain <= rules.null_factor * max(null, 0.0):
        return (f'explains {gain:.1%}, not {rules.null_factor:g}x above the '
                f'{null:.1%} an unrelated (time-shifted) feature explains')
    if drop_pct is not None and drop_pct < rules.min_improvement_pct:
        return (f'lowers the cross-validated RMSE by only {drop_pct:.2f} points '
                f'(< {rules.min_improvement_pct:g})')
    return None
