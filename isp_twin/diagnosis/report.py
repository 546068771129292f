"""The diagnosis report: Markdown with PNG figures, and the Rerun residual recording."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from isp_twin.diagnosis.candidates import BASELINE
from isp_twin.diagnosis.result import Diagnosis
from isp_twin.diagnosis.selection import BLOCK, MIN_GAIN, MIN_SHARE, Z_MIN
from isp_twin.output.files import staged_path, write_text_atomic
from isp_twin.units import DEG

__all__ = ["residual_series", "write_recording", "write_report"]


def residual_series(diag: Diagnosis) -> dict[str, np.ndarray]:
    """Training residuals before/after with angle and rate, counted samples of
    all runs end to end (t restarts nowhere: runs are placed one after the other)."""
    st = diag.stack
    before = np.asarray(diag.residual_before)
    after = np.asarray(diag.residual_after)
    f = st.flat
    n = st.n_samples
    return {
        "t": np.arange(n) * st.dt,
        "before": f(before),
        "after": f(after),
        "angle": f(st.angle),
        "rate": f(st.omega),
    }


def _figure(diag: Diagnosis, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    s = residual_series(diag)
    fig, axes = plt.subplots(2, 3, figsize=(14, 7))
    for ax, key, label in zip(
        axes[0],
        ("t", "angle", "rate"),
        ("time [s] (runs end to end)", "angle [deg]", "rate [deg/s]"),
    ):
        x = s[key] if key == "t" else s[key] / DEG
        ax.plot(x, s["before"] / DEG, ",", alpha=0.5, label="before")
        ax.plot(x, s["after"] / DEG, ",", alpha=0.5, label="after")
        ax.set_xlabel(label)
        ax.set_ylabel("residual [deg/s]")
        ax.legend(markerscale=20)
    a_b, a_a = diag.analysis_before, diag.analysis_after
    lags = np.arange(1, a_b.acf.size + 1)
    axes[1, 0].plot(lags, a_b.acf, label="before")
    axes[1, 0].plot(lags, a_a.acf, label="after")
    axes[1, 0].axhline(a_a.acf_band, color="k", ls=":")
    axes[1, 0].axhline(-a_a.acf_band, color="k", ls=":")
    axes[1, 0].set_xlabel("lag [samples]")
    axes[1, 0].set_ylabel("autocorrelation")
    axes[1, 0].legend()
    for a, lab in ((a_b, "before"), (a_a, "after")):
        f, p = a.spectrum
        axes[1, 1].semilogy(f[1:], p[1:], label=lab)
    axes[1, 1].set_xlabel("frequency [Hz]")
    axes[1, 1].set_ylabel("PSD [(rad/s)^2/Hz]")
    axes[1, 1].legend()
    for a, lab in ((a_b, "before"), (a_a, "after")):
        c, m = a.binned["acceleration"]
        axes[1, 2].plot(c, m / DEG, "o-", label=lab)
    axes[1, 2].set_xlabel("acceleration [rad/s^2]")
    axes[1, 2].set_ylabel("mean residual [deg/s]")
    axes[1, 2].legend()
    fig.suptitle(f"diagnosis of {diag.axis}: residual before and after")
    fig.tight_layout()
    with staged_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=90)
    plt.close(fig)


def _fmt(x: float) -> str:
    return "nan" if not np.isfinite(x) else f"{x:.4g}"


def _none_note(diag: Diagnosis) -> str:
    """After a `none`: its words (`Diagnosis.none_words`), for the headline."""
    if diag.selected_effect != BASELINE:
        return ""
    what, why = diag.none_words()
    return f" ({what})" if why is None else f" ({what}; {why})"


def write_report(diag: Diagnosis, path: Path, params_out: Path | None = None) -> Path:
    """Write the Markdown report to `path` and its figure beside it."""
    path = Path(path)
    png = path.with_suffix(".png")
    _figure(diag, png)
    j = diag.to_json()
    lines = [
        f"# Diagnosis of {diag.axis}",
        "",
        f"Selected effect: **{j['selected_effect']}**" + _none_note(diag),
        "",
        f"Verdict: {j['verdict']}",
        "",
        "| held-out RMS error | rad/s | deg/s |",
        "|---|---|---|",
        f"| given model | {_fmt(diag.rmse_before)} | {_fmt(diag.rmse_before / DEG)} |",
        f"| given model re-identified, no effect | {_fmt(j['rmse_baseline_refit'])} | {_fmt(j['rmse_baseline_refit'] / DEG)} |",
        f"| final model | {_fmt(diag.rmse_after)} | {_fmt(diag.rmse_after / DEG)} |",
        f"| noise floor | {_fmt(diag.noise_floor)} | {_fmt(diag.noise_floor / DEG)} |",
        "",
        f"Held out: {', '.join(diag.holdout_names)}. Noise floor: {diag.analysis_before.noise_method}.",
        "",
    ]
    for i, r in enumerate(diag.rounds, 1):
        lines += [f"## Round {i}: {r.selected}", ""]
        if r.selected != BASELINE:
            m = r.model
            lines += ["| parameter | value | 95 % CI half-width |", "|---|---|---|"]
            lines += [
                f"| {k} | {_fmt(v)} | "
                + ("placed by the held-out run" if k in m.placed else _fmt(m.ci95[k]))
                + " |"
                for k, v in m.params.items()
            ]
            lines.append("")
        lines += [
            "| rank | candidate | held-out RMS [rad/s] | z | delta BIC | significant | reason |",
            "|---|---|---|---|---|---|---|",
        ]
        for k, v in enumerate(r.verdicts, 1):
            lines.append(
                f"| {k} | {v.name} | {_fmt(v.holdout_rmse)} | {v.improvement_z:.2f} | {v.delta_bic:.1f} | "
                f"{'yes' if v.significant else 'no'} | {v.reason} |"
            )
        lines.append("")
    a, b = diag.analysis_before, diag.analysis_after
    lines += [
        "## Residual analysis (training runs)",
        "",
        "| | before | after |",
        "|---|---|---|",
        f"| RMS [rad/s] | {_fmt(a.rms)} | {_fmt(b.rms)} |",
        f"| noise floor [rad/s] | {_fmt(a.noise_floor)} | {_fmt(b.noise_floor)} |",
        f"| autocorrelation lags outside the 95 % band | {a.acf_outside:.0%} | {b.acf_outside:.0%} |",
        f"| white | {a.white} | {b.white} |",
        f"| correlated with the input | {a.input_correlated} | {b.input_correlated} |",
        (
            f"| mean residual moving + / - [rad/s] | {_fmt(a.direction['+'])} / "
            f"{_fmt(a.direction['-'])} | {_fmt(b.direction['+'])} / {_fmt(b.direction['-'])} |"
        ),
        f"| largest spectral peak [Hz] | {_fmt(a.peak_hz)} | {_fmt(b.peak_hz)} |",
        "",
        (
            f"Acceptance rule: held-out MSE improvement > {Z_MIN:g} standard errors of its noise "
            f"term (blocks of {BLOCK} samples), > {MIN_GAIN:g} x noise variance, >= "
            f"{MIN_SHARE:.0%} of the error, and lower BIC (docs/diagnosis.md)."
        ),
        "",
        f"![residuals]({png.name})",
        "",
    ]
    if params_out is not None:
        lines += [f"Updated parameter file: `{params_out}`", ""]
    write_text_atomic(path, "\n".join(lines))
    return path


def write_recording(diag: Diagnosis, path: Path) -> Path:
    """Rerun recording of the training residuals before and after."""
    from isp_twin.output.recording import record_residuals

    s = residual_series(diag)
    j = diag.to_json()
    meta = {
        "selected_effect": j["selected_effect"],
        "effect_parameters": j["effect_parameters"],
        "rmse_before": j["rmse_before"],
        "rmse_after": j["rmse_after"],
        "noise_floor": j["noise_floor"],
    }
    return record_residuals(
        diag.axis,
        s["t"],
        s["before"],
        s["after"],
        path,
        angle=s["angle"],
        rate=s["rate"],
        metadata=meta,
    )
