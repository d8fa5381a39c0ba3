#!/usr/bin/env python3
"""Draws the module map of src/ as an SVG, read from the code (the same rule as tests/cpu/architecture.rs:
top-level module A depends on B when a file of A names `crate::B`, comments and unit tests left out).

Modules are placed in pipeline order: columns by the longest import chain below them (leaves of the graph
on the left, the drivers on the right), rows by name within a column; an arrow goes from a module to what it
uses. Line counts under each name.

    python3 tools/architecture.py > data/readme/architecture.svg
"""
import os
import re
import sys
from collections import defaultdict

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "src")

# Where the data changes form, in pipeline order: the groups are coloured.
GROUPS = {
    "scene": "#dbeafe", "preprocess": "#dbeafe",
    "model": "#fef3c7", "store": "#fef3c7", "texfmt": "#fef3c7", "ids": "#fef3c7",
    "camera": "#dcfce7", "select": "#dcfce7", "paging": "#dcfce7", "plan": "#dcfce7",
    "render": "#fce7f3", "gpu": "#fce7f3", "view": "#fce7f3",
    "sim": "#ede9fe", "sweep": "#ede9fe", "report": "#ede9fe", "inspect": "#ede9fe",
}


def top_module(path):
    rel = os.path.relpath(path, ROOT).split(os.sep)[0]
    name = rel[:-3] if rel.endswith(".rs") else rel
    # `cli` belongs to the binary (it names the library as `atlastree::`, not `crate::`).
    return None if name in ("lib", "main", "cli") else name


def test_files():
    """Files declared `#[cfg(test)] mod NAME;` (test code, as in tests/cpu/architecture.rs)."""
    out = set()
    for dirpath, _, files in os.walk(ROOT):
        for f in files:
            if not f.endswith(".rs"):
                continue
            p = os.path.join(dirpath, f)
            lines = [l.strip() for l in open(p, encoding="utf-8")]
            base = dirpath if f == "mod.rs" else p[:-3]
            for a, b in zip(lines, lines[1:]):
                m = re.fullmatch(r"mod ([a-z_0-9]+);", b)
                if a == "#[cfg(test)]" and m:
                    out.add(os.path.join(base, m.group(1) + ".rs"))
                    out.add(os.path.join(base, m.group(1), "mod.rs"))
    return out


def graph():
    edges, lines = defaultdict(set), defaultdict(int)
    skip = test_files()
    for dirpath, _, files in os.walk(ROOT):
        for f in files:
            if not f.endswith(".rs"):
                continue
            p = os.path.join(dirpath, f)
            m = top_module(p)
            if m is None:
                continue
            edges[m]
            # Unit tests (a `tests.rs` file, a file declared `#[cfg(test)] mod NAME;`, or the
            # `#[cfg(test)] mod NAME {` that ends a file) may use any stage to make their fixtures: they
            # are not the module's dependencies (the rule of tests/cpu/architecture.rs).
            test_code = f == "tests.rs" or p in skip
            cfg_test = False
            for line in open(p, encoding="utf-8"):
                lines[m] += 1
                t = line.strip()
                test_code = test_code or (cfg_test and t.endswith("{"))
                cfg_test = t == "#[cfg(test)]"
                if test_code or cfg_test:
                    continue
                code = line.split("//")[0]
                for dep in re.findall(r"crate::([a-z_0-9]+)", code):
                    if dep != m:
                        edges[m].add(dep)
    return edges, lines


def reduce(edges):
    """The transitive reduction: a → c is left out where a → b → … → c already says it."""

    def reach(m, seen):
        for x in edges.get(m, ()):
            if x not in seen:
                seen.add(x)
                reach(x, seen)
        return seen

    out = {}
    for a, deps in edges.items():
        via = set()
        for b in deps:
            via |= reach(b, set())
        out[a] = {c for c in deps if c not in via}
    return out


def layers(edges):
    depth = {}

    def d(m, seen=()):
        if m in depth:
            return depth[m]
        if m in seen:
            raise SystemExit(f"import cycle through {m}")
        depth[m] = 1 + max((d(x, seen + (m,)) for x in edges.get(m, ())), default=-1)
        return depth[m]

    for m in edges:
        d(m)
    return depth


def main():
    edges, lines = graph()
    depth = layers(edges)
    cols = defaultdict(list)
    for m, k in depth.items():
        cols[k].append(m)
    bw, bh, gx, gy = 118, 40, 52, 18
    height = max(len(v) for v in cols.values()) * (bh + gy) + 60
    width = len(cols) * (bw + gx) + 20
    pos = {}
    for k in sorted(cols):
        for i, m in enumerate(sorted(cols[k])):
            col_h = len(cols[k]) * (bh + gy)
            y0 = (height - 40 - col_h) / 2 + 30
            pos[m] = (10 + k * (bw + gx), y0 + i * (bh + gy))
    out = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
        f'font-family="DejaVu Sans, sans-serif" font-size="12">',
        '<defs><marker id="a" markerWidth="8" markerHeight="8" refX="7" refY="4" orient="auto">'
        '<path d="M0,0 L8,4 L0,8 z" fill="#64748b"/></marker></defs>',
        f'<rect width="{width}" height="{height}" fill="white"/>',
        f'<text x="10" y="18" font-size="13" fill="#334155">atlastree modules: an arrow goes to what a '
        f'module uses, implied arrows left out (read from src/ by tools/architecture.py)</text>',
    ]
    for m, deps in sorted(reduce(edges).items()):
        x0, y0 = pos[m]
        for dep in sorted(deps):
            if dep not in pos:
                continue
            x1, y1 = pos[dep]
            out.append(
                f'<line x1="{x0}" y1="{y0 + bh / 2}" x2="{x1 + bw}" y2="{y1 + bh / 2}" '
                f'stroke="#94a3b8" stroke-width="1" marker-end="url(#a)"/>'
            )
    for m, (x, y) in sorted(pos.items()):
        fill = GROUPS.get(m, "#f1f5f9")
        out.append(
            f'<rect x="{x}" y="{y}" width="{bw}" height="{bh}" rx="6" fill="{fill}" stroke="#475569"/>'
        )
        out.append(f'<text x="{x + bw / 2}" y="{y + 17}" text-anchor="middle" font-weight="bold">{m}</text>')
        out.append(
            f'<text x="{x + bw / 2}" y="{y + 32}" text-anchor="middle" fill="#475569" font-size="10">'
            f"{lines[m]:,} lines</text>"
        )
    out.append("</svg>")
    sys.stdout.write("\n".join(out) + "\n")


if __name__ == "__main__":
    main()
