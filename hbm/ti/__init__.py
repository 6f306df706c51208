"""Time integration with exact Lagrange-multiplier contact: march, sweep, periodicity, validation."""
