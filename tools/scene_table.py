#!/usr/bin/env python3
"""Before/after table of atlastree builds on real scenes (issue 15, "Show").

For every scene: decode time of every used image once (`scene-info --decode`), build with the given flags
(the defaults unless told otherwise), file bytes and their ratio to the source textures as RGB8, atlas
bytes and their ratio, nodes, depth, root min_distance / scene diagonal, and the mean nodes drawn along
`overview-dive` at 800×600 (`render`, tree mode). Prints a markdown table and writes JSON rows.

    tools/scene_table.py --bin target/release/atlastree --out /tmp/table.json \\
        /tmp/real/stk_*/scene.gltf /tmp/real/oa_ctf_inyard/scene.gltf data/city/scene.gltf

Scene-specific flags: `SCENE::--flag,value,...` (e.g. `berlin/scene.gltf::--materials,facade_*,--atlas-size,512`).
A refused build (too large) is a row with the predicted size. Real scenes come from
`shared/realdata/make-scenes.sh`; never commit them.
"""

import argparse
import csv
import json
import os
import re
import subprocess
import sys
import tempfile
import time


# `overview-dive` lasts 20 s: `--frames` samples are spread over all of it.
PATH_SECONDS = 20.0


def run(cmd, timeout):
    t = time.time()
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    return p, time.time() - t


def measure(binary, scene, flags, frames, render, timeout):
    row = {"scene": scene, "flags": " ".join(flags)}
    info, _ = run([binary, "scene-info", scene, "--json", "--decode"] + material_flags(flags), timeout)
    if info.returncode == 0:
        d = json.loads(info.stdout)
        row["source_texels"] = d.get("texture_texels")
        dec = d.get("decode") or {}
        row["decode_s"] = dec.get("seconds") if isinstance(dec, dict) else None
        row["triangles"] = d.get("triangles")
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "scene.atlastree")
        b, secs = run([binary, "build", scene, "-o", out, "--json", "-q"] + flags, timeout)
        row["build_s"] = round(secs, 2)
        if b.returncode != 0:
            last = b.stderr.strip().splitlines()[-1] if b.stderr.strip() else "failed"
            # A build refused as too large says what it would have written (preprocess `TooLarge`); any
            # other failure (a missing scene, a bad flag) is an error of the run, not a refusal.
            m = re.search(r"would need (\d+) nodes \(depth (\d+)\) and (\d+) blocks, a file of (\d+) bytes",
                          b.stderr)
            if not m:
                row["error"] = last
                return row
            row["refused"] = last
            row.update(nodes=int(m[1]), depth=int(m[2]), blocks=int(m[3]), predicted_bytes=int(m[4]))
            return row
        r = json.loads(b.stdout)
        row["file_bytes"] = r["file_bytes"]
        row["diagonal"] = r["scene_diagonal"]
        row["nodes"] = sum(t["nodes"] for t in r["trees"])
        row["depth"] = max(t["depth"] for t in r["trees"])
        row["root_md_over_diag"] = max(t["root_min_distance"] for t in r["trees"]) / r["scene_diagonal"]
        row["atlas_blocks"] = r["atlas_blocks"]
        row["original_blocks"] = r["original_blocks"]
        row["trees"] = [
            {k: t.get(k) for k in ("kind", "nodes", "leaves", "depth", "leaf_reasons", "periods_stored",
                                   "periods_spanned", "root_min_distance")}
            for t in r["trees"]
        ]
        row["atlas_bytes"] = atlas_bytes(binary, out, timeout)
        if render:
            rdir = os.path.join(tmp, "render")
            rr, rsecs = run([binary, "render", out, "--path", "overview-dive", "--out", rdir, "--width", "800",
                             "--height", "600", "--frames", str(frames), "--fps", str(frames / PATH_SECONDS),
                             "--every", "0", "--warmup", "1",
                             "--no-gpu-timing"], timeout)
            row["render_s"] = round(rsecs, 1)
            stats = os.path.join(rdir, "stats.csv")
            if rr.returncode == 0 and os.path.exists(stats):
                with open(stats) as f:
                    rows = list(csv.DictReader(f))
                drawn = [float(x["nodes_drawn"]) for x in rows]
                row["nodes_drawn_mean"] = sum(drawn) / len(drawn)
                row["nodes_drawn_max"] = max(drawn)
            else:
                row["render_error"] = (rr.stderr or "").strip()[-300:]
    return row


def atlas_bytes(binary, path, timeout):
    """Bytes of the atlas blocks (not the original-texture blocks), from `inspect --json`'s per-tree counts."""
    p, _ = run([binary, "inspect", path, "--json"], timeout)
    if p.returncode != 0:
        return None
    d = json.loads(p.stdout)
    d = d.get("inspect", d)
    atlas = d["params"]["atlas_size"]
    total = 0
    for t in d["trees"]:
        # A 4×4 block of texels takes bytes_per_block bytes; a full chain down to 1×1 of a side-s atlas.
        s, chain = atlas, 0
        while True:
            chain += max(1, (s + 3) // 4) ** 2 * t["bytes_per_block"]
            if s == 1:
                break
            s //= 2
        total += chain * t["atlas_blocks"]
    return total


def material_flags(flags):
    out = []
    for i, f in enumerate(flags):
        if f == "--materials" and i + 1 < len(flags):
            out += [f, flags[i + 1]]
    return out


def fmt_bytes(n):
    if n is None:
        return "—"
    for unit, k in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= k:
            return f"{n / k:.2f} {unit}"
    return f"{n} B"


def table(rows):
    head = ("| scene | build | decode | file | file ÷ RGB8 | atlases ÷ RGB8 | nodes | depth | root md ÷ diag "
            "| nodes drawn mean (max) |\n|---|---|---|---|---|---|---|---|---|---|")
    lines = [head]
    for r in rows:
        rgb8 = 3 * (r.get("source_texels") or 0)
        name = os.path.basename(os.path.dirname(r["scene"])) or r["scene"]
        if "error" in r:
            lines.append(f"| {name} | failed: {r['error']} | — | — | — | — | — | — | — | — |")
            continue
        decode = f"{r['decode_s']:.2f}" if r.get("decode_s") is not None else "—"
        if "refused" in r:
            lines.append(f"| {name} | refused ({r['build_s']} s) | {decode} s | "
                         f"{fmt_bytes(r.get('predicted_bytes'))} predicted | "
                         f"{(r.get('predicted_bytes') or 0) / max(rgb8, 1):.0f}× | — | {r.get('nodes', '—')} | "
                         f"{r.get('depth', '—')} | — | — |")
            continue
        ab = r.get("atlas_bytes")
        drawn = (f"{r['nodes_drawn_mean']:.1f} ({r['nodes_drawn_max']:.0f})" if "nodes_drawn_mean" in r
                 else "—")
        lines.append(
            f"| {name} | {r['build_s']} s | {r.get('decode_s') or 0:.2f} s | {fmt_bytes(r['file_bytes'])} | "
            f"{r['file_bytes'] / max(rgb8, 1):.2f}× | {(ab or 0) / max(rgb8, 1):.2f}× | {r['nodes']} | "
            f"{r['depth']} | {r['root_md_over_diag']:.3f} | {drawn} |")
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenes", nargs="+")
    ap.add_argument("--bin", default="target/release/atlastree")
    ap.add_argument("--flags", default="--compress,bc1", help="build flags for every scene, comma-separated")
    ap.add_argument("--frames", type=int, default=120)
    ap.add_argument("--no-render", action="store_true")
    ap.add_argument("--timeout", type=int, default=3600)
    ap.add_argument("--out", help="write the rows as JSON here")
    a = ap.parse_args()
    common = [f for f in a.flags.split(",") if f]
    rows = []
    for spec in a.scenes:
        scene, _, extra = spec.partition("::")
        flags = common + [f for f in extra.split(",") if f]
        print(f"== {scene} {' '.join(flags)}", file=sys.stderr, flush=True)
        row = measure(a.bin, scene, flags, a.frames, not a.no_render, a.timeout)
        print(json.dumps(row), file=sys.stderr, flush=True)
        rows.append(row)
        if a.out:
            with open(a.out, "w") as f:
                json.dump(rows, f, indent=1)
    print(table(rows))
    failed = [r["scene"] for r in rows if "error" in r]
    if failed:
        print(f"scene_table.py: {len(failed)} scene(s) failed to build: {', '.join(failed)}", file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
