"""Paper vs twin, full size: Table 4 grid and the Table 5 / 6 campaigns with ten seeds.

Writes docs/paper_vs_twin.md (the same text as `isp-twin report --output ...`)
and prints it, with the wall time. Usage::

    python benchmarks/paper_tables.py [--runs 10] [--jobs 2]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from isp_twin.atomic import write_text_atomic
from isp_twin.campaign import compare_with_paper, comparison_markdown


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--output", type=Path,
                        default=Path(__file__).resolve().parents[1] / "docs" / "paper_vs_twin.md")
    args = parser.parse_args()
    start = time.perf_counter()
    text = comparison_markdown(compare_with_paper(args.runs, args.jobs))
    elapsed = time.perf_counter() - start
    write_text_atomic(args.output, text)
    print(text)
    print(f"wall time {elapsed:.1f} s with {args.jobs} workers; written to {args.output}")


if __name__ == "__main__":
    main()
