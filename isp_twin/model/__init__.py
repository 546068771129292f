"""The plant: parameter sets, the friction law (Eq. 5), the discrete axis
model (Eq. 6) and its sub-stepped form, the MuJoCo twin and the library of
extra physical effects. Imports nothing from the experiments, identification,
diagnosis or commands above it (tests/test_architecture.py)."""
