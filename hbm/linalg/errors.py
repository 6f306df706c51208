"""The one error of the linear-algebra layer."""
from __future__ import annotations


class SingularMatrixError(RuntimeError):
    """A factorisation met a zero pivot, or a solve gave non-finite numbers.

    Newton loops catch it and report the point as not converged, with this message as the
    reason; the bordered solve catches it to fall back to the full bordered matrix.
    """
