"""Search for the solution branches the primary NFRC does not reach (section 3.2 of the reference paper).

options: IsolaOptions (scene section [isolas]). seeds: the start guesses, eq. (31) modal
seeds (from rest, and around the primary NFRC's solutions) and periodic time-integration
points. membership: whether a solution lies on a known
branch. search: the engine, generic over a residual R(x, omega). harmonic: the HBM residual
side (factory, seeds, per-point data).
"""
