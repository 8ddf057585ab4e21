#!/usr/bin/env python3
"""The strong and weak scaling model of docs/distributed.md, as Markdown tables.

c: measured per particle-step per core (mpm bench --cases jello --particles 200000
--threads 1); alpha, beta: assumed network latency and bandwidth; s: substeps per frame.
"""
import math
import sys

c = float(sys.argv[1]) if len(sys.argv) > 1 else 297e-9  # s per particle-step, one core
alpha, beta, s = 2e-6, 10e9, 42
node_bytes, record_bytes = 56, 128


def row(n, r):
    edge = (n / 8) ** (1 / 3)  # cells across a cube body at 8 particles per cell
    layers = int(edge / 4)
    compute = c * n / r
    halo = 2 * alpha + node_bytes * 4 * edge**2 / beta
    reductions = 9 * alpha * math.log2(r)
    gather = 2 * n * record_bytes / (beta * s)
    t = compute + halo + reductions + gather
    note = "" if r <= layers else " (refused today: more ranks than layers)"
    return (f"| {n:.3g} | {r} | {layers} | {compute*1e3:.3g} | {halo*1e3:.3g} | "
            f"{reductions*1e3:.2g} | {gather*1e3:.3g} | {t*1e3:.3g} | {compute/t:.2f}{note} |")


head = ("| N | R | block layers | compute ms | halo ms | reductions ms | gather ms | "
        "T ms per substep | compute / T |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
print("Strong scaling\n\n" + head)
for n in (1e7, 1e8, 1e9):
    for r in (8, 64, 512):
        print(row(n, r))
print("\nWeak scaling, 2M particles per rank\n\n" + head)
for r in (8, 64, 512):
    print(row(2e6 * r, r))
