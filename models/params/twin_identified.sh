#!/usr/bin/env bash
# Regenerates models/params/twin_identified.yaml: the model the twin's NFC
# compensates with by default (rig knob nfc_model), identified the way the
# paper identified its model (Sect. 3): Eq. 7 open-loop runs of each inner
# gimbal on the MuJoCo twin, with the generator's gyro noise (0.02 deg/s,
# 1 sigma) and 16-bit resolver quantization, then `isp-twin identify`
# (seeded: the same file every time). --substeps 1: the twin steps its
# friction once per 1 ms sample (explicit Euler, docs/axis_model.md), which is
# Eq. 6 itself, so the identification model is Eq. 6 (identify's default of
# 10 sub-steps is for real axes, whose friction changes within a sample).
# Usage, from anywhere:
#   bash models/params/twin_identified.sh [OUT]    (default: the shipped file)
# tests/test_nfc_model.py runs it and compares with the shipped file.
# ISP_TWIN overrides the command (e.g. "python -m isp_twin.cli").
set -euo pipefail
isp_twin=${ISP_TWIN:-isp-twin}
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
out="${1:-$here/twin_identified.yaml}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
$isp_twin generate --out "$work/inner_az" --axis inner_az --set paper --engine twin --seed 0 --quiet
$isp_twin generate --out "$work/inner_el" --axis inner_el --set paper --engine twin --seed 4 --quiet
$isp_twin identify "$work"/inner_az/*.csv --axis inner_az --prior "$here/paper_table2.yaml" \
    --out "$work/twin_identified_inner_az.yaml" --substeps 1 --no-report --quiet
$isp_twin identify "$work"/inner_el/*.csv --axis inner_el --prior "$work/twin_identified_inner_az.yaml" \
    --out "$out" --substeps 1 --no-report --quiet
