"""Controller blocks of the rate loops: plain numpy, no MuJoCo."""
