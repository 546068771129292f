"""Design sweeps: many closed-loop runs described in one file, run on Dask, kept in SQLite.

`design` checks a sweep file and expands it into runs, `execute` runs them
(in process or on a Dask cluster), `store` keeps each finished run in an
SQLite file keyed by the hash of its inputs, `summary` reads the store back
into tables and plots of J against each knob.
"""
