"""What a branch's per-point data holds where it has no value: a point not described (it did
not converge), or written before a run that records that datum."""
from __future__ import annotations

import numpy as np

#: By numpy dtype kind: nan (complex: nan in both parts, a value h5py also writes as a
#: complex dataset's fill value, which a float nan is not), False, -1 for a signed count
#: (n_unstable -1: unknown, as in the NFRC files; a 0 there reads "no multiplier out"), 0 for
#: an unsigned one. Text is the writer's own: why there is no value, or "".
NO_VALUE = {"f": np.nan, "c": complex(np.nan, np.nan), "b": False, "i": -1, "u": 0}
