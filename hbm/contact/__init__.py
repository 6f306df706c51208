"""Contact on time samples: the casing of eq. (28), normal laws, sliding friction."""
