"""The leader test's false-best rate and power, simulated through hnnbench's own marking
function (``hnnbench._results.families.simulate_marks`` drives ``mark_best``).

    python scripts/analysis/leader_test_power.py [--draws 2000] [--seed 0]

Prints the two Markdown tables of docs/STATISTICS.md ("The leader test, simulated"):
the share of cells marked best among k identical families over n paired seeds (the
false-best rate, the leader's choice included), and the share where the one better
family is marked best when its log-values are shifted by an effect (in units of the
per-seed standard deviation of a family's own log-value).
"""

from __future__ import annotations

import argparse

from hnnbench._results.families import simulate_marks
from hnnbench._results.stats import MIN_SEPARABLE_SEEDS

FAMILIES = (2, 3, 4, 5, 6)
SEEDS = (5, 10)
EFFECTS = (0.5, 1.0, 1.5, 2.0, 3.0)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--draws", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--power-only", action="store_true", help="leave out the false-best table")
    args = parser.parse_args(argv)
    if not args.power_only:
        print(f"False-best rate ({args.draws} draws each, seed {args.seed}):\n")
        print("| families k | " + " | ".join(f"n = {n}" for n in SEEDS) + " |")
        print("|---|" + "---|" * len(SEEDS))
        for k in FAMILIES:
            cells = [
                simulate_marks(k, n, args.draws, "energy_mse", seed=args.seed)["any_best"]
                for n in SEEDS
            ]
            print(f"| {k} | " + " | ".join(f"{c:.1%}" for c in cells) + " |", flush=True)
    for n in [n for n in SEEDS if n >= MIN_SEPARABLE_SEEDS]:  # below it, 0 by construction
        print(f"\nPower at n = {n} seeds: the better family marked best, by effect:\n")
        print("| families k | " + " | ".join(f"effect {e:g}" for e in EFFECTS) + " |")
        print("|---|" + "---|" * len(EFFECTS))
        for k in FAMILIES:
            cells = [
                simulate_marks(k, n, args.draws, "energy_mse", effect=e, seed=args.seed)["power"]
                for e in EFFECTS
            ]
            print(f"| {k} | " + " | ".join(f"{c:.0%}" for c in cells) + " |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
