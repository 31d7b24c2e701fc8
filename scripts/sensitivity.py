#!/usr/bin/env python3
"""One-factor-at-a-time sensitivity table from `plugflow sweep` folders (issue 25, item 2).

Usage: sensitivity.py REFERENCE_SWEEP [SWEEP ...]

Each sweep varies one factor over seeds (`--vary FIELD=VALUE --vary seed=1,2,3`). For each
sweep the rows V1–V5 of its variants' summaries are averaged over the seeds (mean ± sample
standard deviation) and compared with the reference sweep's: the change in standard errors
of the difference, sqrt(s_a²/n_a + s_b²/n_b), so that a change inside the seed-to-seed
scatter reads |z| < 2. Prints a Markdown table."""
import json
import math
import pathlib
import sys

ROWS = [
    ("V1", "V1 Δp, hPa/m", "{:.1f}"),
    ("V2", "V2 grains", "{:.0f}"),
    ("V3", "V3 max v, m/s", "{:.3f}"),
    ("V3.tracked", "V3 tracked, m/s", "{:.3f}"),
    ("V4", "V4 length, m", "{:.3f}"),
    ("V5", "V5 min φ", "{:.4f}"),
]


def variants(folder):
    """(label of the non-seed settings, {row: [values]}, wall seconds) of one sweep."""
    label, values, wall = None, {r: [] for r, _, _ in ROWS}, []
    for summary in sorted(pathlib.Path(folder).glob("*/summary.json")):
        s = json.loads(summary.read_text())
        measured = {t["id"]: t["measured"] for t in s.get("targets", [])}
        for r, _, _ in ROWS:
            if measured.get(r) is not None:
                values[r].append(measured[r])
        wall.append(s["wall_time_s"])
        name = summary.parent.name
        parts = [p for p in name.split("_") if not p.startswith("seed")]
        label = label or " ".join(parts)
    return label or folder, values, wall


def stats(v):
    n = len(v)
    if n == 0:
        return None
    mean = sum(v) / n
    sd = math.sqrt(sum((x - mean) ** 2 for x in v) / (n - 1)) if n > 1 else float("nan")
    return mean, sd, n


def main():
    folders = sys.argv[1:]
    if not folders:
        sys.exit(__doc__)
    table = [variants(f) for f in folders]
    ref = {r: stats(v) for r, v in table[0][1].items()}
    head = "| variant (folder) | " + " | ".join(h for _, h, _ in ROWS) + " | wall, s |"
    print(head)
    print("|" + " --- |" * (len(ROWS) + 2))
    for folder, (label, values, wall) in zip(folders, table):
        cells = []
        for r, _, fmt in ROWS:
            st = stats(values[r])
            if st is None:
                cells.append("–")
                continue
            mean, sd, n = st
            cell = f"{fmt.format(mean)} ± {fmt.format(sd)}"
            if folder != folders[0] and ref[r] is not None:
                m0, s0, n0 = ref[r]
                se = math.sqrt(s0 * s0 / n0 + sd * sd / n)
                if se > 0:
                    z = (mean - m0) / se
                    cell += f" ({z:+.1f})" if abs(z) < 2 else f" (**{z:+.1f}**)"
            cells.append(cell)
        median_wall = sorted(wall)[len(wall) // 2] if wall else float("nan")
        name = pathlib.Path(folder).name
        print(f"| {name} | " + " | ".join(cells) + f" | {median_wall:.0f} |")


if __name__ == "__main__":
    main()
