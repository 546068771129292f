"""What is run on the plant: scenarios and the rig, the closed loop (Python
and compiled), open-loop runs, metrics (Eq. 10), campaigns, uncertainty,
calibration against the paper's tables, and sweeps."""
