"""Controller blocks of the rate loops: plain numpy, no MuJoCo.

One module per block: `pi`, `notch`, `bound`, `nfc` (Eq. 11-14), `gyro`,
`resolver`, `follower` (outer gimbals), and `rate_loop` composing the inner loop.
"""
