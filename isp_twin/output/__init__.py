"""Everything a command writes: files as one transaction, and Rerun recordings.

- `files`: output destinations checked up front, a command's files written as
  one transaction (`staged_path`, `transaction`, `write_text_atomic`).
- `recording`: what a run's or a diagnosis's recording holds (`record_run`,
  `record_residuals`).
- `entities`: where each signal goes in a recording, in which display unit.
- `kinematics`: the drawn joints' rotations and the line of sight (numpy).
- `layout`: the views a recording opens with (Rerun blueprints).
- `rerun_writer`: the stream saved atomically, Ctrl-C held, a viewer fed.
- `readback`: verify a recording and read it back (tests, reports).

Only this package imports rerun (tests/test_architecture.py). This file
imports nothing, so that `files` does not pull rerun into every command.
"""
