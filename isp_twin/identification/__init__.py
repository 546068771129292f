"""From measured runs to parameters: measured data in, the twin's own
identification experiments (Eq. 7), the fit (Eq. 8-9), its verdict against
the noise floor, and its report."""
