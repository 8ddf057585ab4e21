#!/usr/bin/env python3
"""Checks the layer order of the engine's include graph.

Usage: check_layers.py REPO_ROOT   (the ctest "include layers point down"; docs/architecture.md)

Layers, lowest first:
  core < materials < scene < step < parallel < run < io < tools < cli < apps
(engine/core, materials/, engine/scene, engine/step, engine/parallel, engine/run, engine/io,
engine/tools, engine/cli, apps/). A file may include headers of its own layer or a lower one.
Every `#include "..."` in engine/, materials/ and apps/ that names a header of a higher layer
is printed as

  FILE:LINE: includes HEADER (layer A) from layer B

and the script exits 1; with none it exits 0. Headers outside these folders (system headers,
third-party headers, generated files) are ignored. Source files in engine/ outside every
layer folder are reported on stderr (not an error), so a new folder is not silently unchecked.
Stdlib only.
"""

import os
import re
import sys

from source_tree import source_files

LAYERS = ["core", "materials", "scene", "step", "parallel", "run", "io", "tools", "cli", "apps"]
RANK = {name: i for i, name in enumerate(LAYERS)}

# Path prefix (relative to the repository root, '/'-separated) -> layer. Longest prefix wins.
PREFIXES = {
    "engine/core/": "core",
    "materials/": "materials",
    "engine/scene/": "scene",
    "engine/step/": "step",
    "engine/parallel/": "parallel",
    "engine/run/": "run",
    "engine/io/": "io",
    "engine/tools/": "tools",  # with tools/validation/
    "engine/cli/": "cli",
    "apps/": "apps",
}
SCANNED_ROOTS = ("engine", "materials", "apps")

INCLUDE_RE = re.compile(r'^\s*#\s*include\s*"([^"]+)"')


def layer_of(rel):
    """The layer of repository-relative path `rel`, or None."""
    best = None
    for prefix, layer in PREFIXES.items():
        if rel.startswith(prefix) and (best is None or len(prefix) > len(best[0])):
            best = (prefix, layer)
    return best[1] if best else None


def resolve(root, includer_rel, name):
    """Repository-relative path of header `name`: as the project spells it (from the root, the
    include directory every target has), else relative to the including file. None if the
    header is not a file of the tree (then it is not ours to check)."""
    name = name.replace("\\", "/")
    candidates = [os.path.normpath(name),
                  os.path.normpath(os.path.join(os.path.dirname(includer_rel), name))]
    for rel in candidates:
        rel = rel.replace(os.sep, "/")
        if rel.startswith("../"):
            continue
        if os.path.isfile(os.path.join(root, rel)):
            return rel
    # Not in the tree (generated, or a typo the compiler will report): judge by its spelling.
    rel = os.path.normpath(name).replace(os.sep, "/")
    return rel if layer_of(rel) else None


def include_lines(path):
    """(line number, included name) of every quoted include outside block comments."""
    out = []
    in_block = False
    with open(path, encoding="utf-8", errors="replace") as f:
        for number, line in enumerate(f, 1):
            text = line
            if in_block:
                end = text.find("*/")
                if end < 0:
                    continue
                text = text[end + 2:]
                in_block = False
            # A block comment opened on this line before any directive hides the rest.
            start = text.find("/*")
            if start >= 0 and text.find("*/", start + 2) < 0:
                in_block = True
                text = text[:start]
            m = INCLUDE_RE.match(text)
            if m:
                out.append((number, m.group(1)))
    return out


def main(argv):
    if len(argv) != 2 or not os.path.isdir(argv[1]):
        print("usage: check_layers.py REPO_ROOT", file=sys.stderr)
        return 2
    root = os.path.abspath(argv[1])
    violations = []
    files = 0
    for full, rel in source_files(root, SCANNED_ROOTS):
        src_layer = layer_of(rel)
        if src_layer is None:
            print(f"note: {rel} lies in no layer folder; not checked", file=sys.stderr)
            continue
        files += 1
        for number, name in include_lines(full):
            target = resolve(root, rel, name)
            if target is None:
                continue
            dst_layer = layer_of(target)
            if dst_layer is None:
                continue
            if RANK[dst_layer] > RANK[src_layer]:
                violations.append((rel, number, target, dst_layer, src_layer))
    for rel, number, target, dst, src in violations:
        print(f"{rel}:{number}: includes {target} (layer {dst}) from layer {src}")
    order = " < ".join(LAYERS)
    if violations:
        print(f"{len(violations)} up-include(s) in {files} files (order: {order})",
              file=sys.stderr)
        return 1
    print(f"no up-includes in {files} files (order: {order})", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
