"""``isp-twin generate``: the paper's open-loop identification runs, from the twin."""

from __future__ import annotations

from pathlib import Path

from isp_twin.commands.generate_reference import add_reference_options, execute_reference
from isp_twin.identification.experiments import (
    EQ7,
    GYRO_NOISE_DEG_S,
    RESOLVER_LSB_DEG,
    check_excitation,
    generate_openloop,
    paper_set,
)
from isp_twin.identification.measured import save_measured
from isp_twin.model.parameters import load_parameters
from isp_twin.output.files import check_folder, check_outputs, transaction
from isp_twin.resources import default_parameters_path
from isp_twin.vocabulary import GIMBAL_AXES


def add_parser(sub) -> None:
    p = sub.add_parser(
        "generate",
        help="simulate open-loop identification runs (Eq. 7) as measured-data CSV files",
        description=(
            "Simulate the paper's open-loop identification experiment (Eq. 7: "
            "u = A cos(2 pi f t) + offset digits) with known parameters, add gyro noise and "
            "resolver quantization, and write canonical CSV files (t, u, omega [deg/s], theta [deg]). "
            "--set paper writes the four variations that visit all regimes without reaching a "
            "stop (their own set for inner_el); --set eq7 one run "
            "with the options below."
        ),
    )
    p.add_argument("--out", required=True, type=Path, help="output folder")
    p.add_argument("--params", type=Path, default=None, help="true parameters (default: Table 2)")
    p.add_argument("--axis", default="inner_az", choices=GIMBAL_AXES)
    p.add_argument("--set", default="paper", choices=("paper", "eq7"), dest="which")
    p.add_argument("--amplitude", type=float, default=EQ7.amplitude_digits, help="[digits]")
    p.add_argument("--freq", type=float, default=EQ7.freq_hz, help="[Hz]")
    p.add_argument("--offset", type=float, default=EQ7.offset_digits, help="[digits]")
    p.add_argument("--samples", type=int, default=EQ7.n_samples)
    p.add_argument("--initial-angle", type=float, default=0.0, help="[deg]")
    p.add_argument("--gyro-noise", type=float, default=GYRO_NOISE_DEG_S, help="1 sigma [deg/s]")
    p.add_argument("--resolver-lsb", type=float, default=RESOLVER_LSB_DEG, help="[deg]")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--engine", default="fast", choices=("fast", "twin"))
    p.add_argument("--quiet", action="store_true")
    add_reference_options(p)
    p.set_defaults(execute=execute)


def execute(args) -> int:
    if args.reference or args.effect is not None or args.held_out is not None:
        return execute_reference(args)
    params_path = args.params or default_parameters_path()
    if args.which == "paper":
        runs = [
            (
                e.amplitude_digits,
                e.freq_hz,
                e.offset_digits,
                e.n_samples,
                e.initial_angle_deg,
                e.name,
            )
            for e in paper_set(args.axis)
        ]
    else:
        runs = [(args.amplitude, args.freq, args.offset, args.samples, args.initial_angle, "eq7")]
    for amp, freq, off, n, y0, _ in runs:
        check_excitation(
            amplitude_digits=amp,
            freq_hz=freq,
            offset_digits=off,
            n_samples=n,
            initial_angle_deg=y0,
            gyro_noise_deg_s=args.gyro_noise,
            resolver_lsb_deg=args.resolver_lsb,
            seed=args.seed,
        )
    check_folder("--out", args.out)
    paths = {f"--out {name}.csv": args.out / f"{name}.csv" for *_, name in runs}
    check_outputs(paths, inputs=[params_path])
    params = load_parameters(params_path)
    generated = []
    for i, (amp, freq, off, n, y0, name) in enumerate(runs):
        data = generate_openloop(
            params,
            args.axis,
            amplitude_digits=amp,
            freq_hz=freq,
            offset_digits=off,
            n_samples=n,
            dt=params.sample_time_s,
            gyro_noise_deg_s=args.gyro_noise,
            resolver_lsb_deg=args.resolver_lsb,
            seed=args.seed + i,
            engine=args.engine,
            initial_angle_deg=y0,
            name=name,
        )
        generated.append((data, args.out / f"{name}.csv"))
    with transaction():
        for data, path in generated:
            save_measured(data, path)
    if not args.quiet:
        for data, path in generated:
            print(f"wrote {path} ({len(data)} samples)")
    return 0
