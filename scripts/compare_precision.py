"""Pairs the rows of two `mpm study` CSVs (float and double particle storage) and prints a
Markdown table: each setting's error in both builds and the float/double wall-time ratio."""
import csv
import sys


def rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


KEY = ("experiment", "case", "kernel", "h", "ppc", "sampling", "cfl", "dt", "transfer")


def main(float_csv, double_csv):
    doubles = {tuple(r[k] for k in KEY): r for r in rows(double_csv)}
    print("| experiment | setting | error (what) | float | double | time float / double |")
    print("| --- | --- | --- | ---: | ---: | ---: |")
    for f in rows(float_csv):
        d = doubles.get(tuple(f[k] for k in KEY))
        if d is None:
            continue
        setting = "%s h=%s ppc=%s %s %s" % (f["kernel"], f["h"], f["ppc"], f["sampling"],
                                             f["transfer"])
        if f["experiment"] == "dt":
            setting += " dt=%s" % f["dt"]
        ratio = float(f["wall_seconds"]) / max(float(d["wall_seconds"]), 1e-12)
        print("| %s | %s | %s | %.3g | %.3g | %.2f |" % (
            f["experiment"], setting, f["error_name"], float(f["error"]), float(d["error"]), ratio))


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: compare_precision.py FLOAT_STUDY.csv DOUBLE_STUDY.csv")
    main(sys.argv[1], sys.argv[2])
