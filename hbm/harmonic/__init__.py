"""Harmonic balance on the condensed ROM: AFT, residual, structured Jacobian and solver, NFRC."""
