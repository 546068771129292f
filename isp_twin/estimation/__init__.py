"""The estimation engine identify and diagnose share: the least-squares
solver, the confidence intervals, the information criterion, the way from a
fitted vector to a parameter file, and the verdict against the noise floor."""
