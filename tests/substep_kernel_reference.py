"""The sub-step kernel as it was before its rows were interleaved and run in
parallel (`isp_twin.model.substep_model` at commit 9cc08c3): one row after the other,
the obvious loop. `tests/test_substep_model.py` checks the fast kernel against
it bit for bit. Not cached: compiled once per test session. The side of
angle 0 follows the direction (`isp_twin.model.friction.side_of`, the
boundary rule added after 9cc08c3). With `by_drive` the gain at rest is
the gain of the regime the total drive breaks towards
(`Integration.rest_drive_gain`, added at stop 21); from angle 0 a break
towards + passes L+'s level too (Eq. 5's Y = 0, added at stop 42). With
`mid` a breakaway sub-step takes the sliding friction at its mean rate
(added at stop 42)."""

from numba import njit

from isp_twin.model import friction_compiled as law


@njit(nogil=True)
def _regime(angle, direction, fixed_side):
    """The regime of a motion in `direction` at `angle`, or on `fixed_side`
    (the side of angle 0 by the direction: the law since the boundary rule)."""
    side = fixed_side if fixed_side >= 0 else law.side_of(angle, direction)
    return law.regime_of(side, direction)


@njit(nogil=True)
def _rest_gain_regime(table, i, ys, uk, ek, fixed_side, by_drive):
    """At rest: the regime whose gain drives the step, and whether it breaks
    free at all (decided here only with `by_drive`; else by the caller)."""
    if by_drive:
        for direction in (1.0, -1.0):
            r = _regime(ys, direction, fixed_side)
            d = table[i, r, 1] * uk + table[i, r, 5] * ek
            if direction * d > table[i, r, 2]:
                if ys == 0.0 and direction > 0.0 and fixed_side < 0:
                    # From angle 0 (Eq. 5's L) the + break passes L+ first.
                    left = _regime(-1.0, 1.0, fixed_side)
                    if table[i, left, 1] * uk + table[i, left, 5] * ek <= table[i, left, 2]:
                        continue
                return r, True
        return _regime(ys, uk, fixed_side), False
    return _regime(ys, uk, fixed_side), True


@njit(nogil=True)
def advance_row_by_row(
    table,
    u,
    extra,
    side_y,
    use_side,
    fixed_side,
    k_lo,
    k_hi,
    m,
    dt,
    mid,
    split,
    by_drive,
    w_state,
    y_state,
    point,
    reading,
    angle,
    regime,
):  # pragma: no cover - compiled
    """Advance every row from sample k_lo-1 to k_hi-1 (writes columns k_lo..k_hi-1).

    table: (S, 4, 5) per-sub-step (p, c·gain, c·static, c·coulomb, alpha) and
    and the effects' factor in column 5 of a (S, 4, 6) table (`_substep_table`);
    u, extra: (S, N) per-sample command
    and extra drive [rate form per sample]; side_y: (S, N) angle choosing the
    half-plane (used when use_side); fixed_side: -1 none, else the side index.
    """
    n_rows = u.shape[0]
    h = dt / m
    for i in range(n_rows):
        w = w_state[i]
        y = y_state[i]
        for k in range(k_lo, k_hi):
            uk = u[i, k - 1]
            ek = extra[i, k - 1]
            acc = 0.5 * w
            idx = 0
            for j in range(m):
                if use_side:
                    y0 = side_y[i, k - 1]
                    if j == 0:
                        ys = y0
                    else:
                        ys = y0 + (j / m) * (side_y[i, k] - y0)
                else:
                    ys = y
                if w != 0.0:
                    idx = _regime(ys, w, fixed_side)
                    p = table[i, idx, 0]
                    drive = table[i, idx, 1] * uk + table[i, idx, 5] * ek
                    ts = table[i, idx, 2]
                    tc = table[i, idx, 3]
                    al = table[i, idx, 4]
                    slide = law.sliding(w, ts, tc, al)
                    w_new = p * w + drive - slide
                    if mid and w_new * w > 0.0:
                        wm = 0.5 * (w + w_new)
                        slide = law.sliding(wm, ts, tc, al)
                        w_new = p * w + drive - slide
                    if w_new * w <= 0.0:
                        rest_part = 0.0
                        if split and w_new != 0.0:
                            rest_part = 1.0 - w / (w - w_new)
                        w_new = 0.0
                        if rest_part > 0.0:
                            # The rest of the sub-step starts at rest.
                            r0, free = _rest_gain_regime(table, i, ys, uk, ek, fixed_side, by_drive)
                            d = table[i, r0, 1] * uk + table[i, r0, 5] * ek
                            idx = _regime(ys, d, fixed_side)
                            ts2 = table[i, idx, 2]
                            if free and abs(d) > ts2:
                                w_new = rest_part * (d - law.stiction(d, ts2))
                                if mid:  # the breakaway's friction at its mean rate
                                    slide = law.sliding(0.5 * w_new, ts2, table[i, idx, 3],
                                                        table[i, idx, 4])  # fmt: skip
                                    w_new = rest_part * (d - slide)
                    w = w_new
                else:
                    # At rest the command's sign (or with `by_drive` the
                    # breakaway's direction) picks the gain and the total
                    # drive's sign the breakaway level.
                    r0, free = _rest_gain_regime(table, i, ys, uk, ek, fixed_side, by_drive)
                    d = table[i, r0, 1] * uk + table[i, r0, 5] * ek
                    idx = _regime(ys, d, fixed_side)
                    ts = table[i, idx, 2]
                    if free and abs(d) > ts:
                        w = d - law.stiction(d, ts)
                        if mid:  # the breakaway's friction at its mean rate
                            w = d - law.sliding(0.5 * w, ts, table[i, idx, 3], table[i, idx, 4])
                    else:
                        w = 0.0
                y = y + h * w
                if j < m - 1:
                    acc += w
                else:
                    acc += 0.5 * w
            point[i, k] = w
            reading[i, k] = acc / m
            angle[i, k] = y
            regime[i, k] = idx
        w_state[i] = w
        y_state[i] = y
