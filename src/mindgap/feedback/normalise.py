"""Per-person rating normalisation (§2.3.2: "the ratings are normalized to remove
inconsistencies across different participants").

People use a rating slider differently: one never goes above 8, another never below
2. The rating model (``γ_max`` times the geometric mean of the person's policy) has one
absolute scale, so each person's ratings are mapped onto it before fitting.
"""

from __future__ import annotations

import numpy as np

METHODS = ("minmax", "none")


def normalise_ratings(ratings, method: str = "minmax", gamma_max: float = 10.0) -> np.ndarray:
    """One person's ratings ``[N]`` on the full scale.

    Args:
        ratings: the person's ratings, all in ``[0, γ_max]``.
        method: ``minmax`` maps their lowest rating to 0 and their highest to ``γ_max``
            (linearly); ``none`` returns them unchanged.
        gamma_max: top of the scale.

    Raises:
        ValueError: an unknown method, or ``minmax`` on ratings that are all equal
            (nothing to learn from them).
    """
    r = np.asarray(ratings, np.float64)
    if method == "none":
        return r
    if method != "minmax":
        raise ValueError(f"unknown normalisation {method!r}: use one of {', '.join(METHODS)}")
    span = np.ptp(r) if r.size else 0.0
    if span == 0:
        raise ValueError("every demonstration got the same rating; min-max normalisation is undefined")
    return (r - r.min()) / span * gamma_max
