#!/usr/bin/env python3
"""Paging before/after (issue 17): `simulate` along overview-dive and street, paper policy, 5 and 50 MB/s,
no latency, 40 s at 30 fps, the same k for every file of a scene. One row per (file, path, bandwidth):
mean coarser share, bytes loaded (all, originals), loads, frames to the ideal set after each jump.

    tools/paging_cmp.py --k 40 v3=/tmp/v3_atlastree:/tmp/cf_v3.atlastree now=target/release/atlastree:/tmp/cf.atlastree

Each LABEL=BIN:FILE is simulated with its own binary (a file is read by the binary of its format).
"""
import argparse
import sys
import json
import subprocess
import tempfile


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--k", type=int, required=True, help="capacity k (blocks)")
    ap.add_argument("--paths", default="overview-dive,street")
    ap.add_argument("--bandwidths", default="5MB/s,50MB/s")
    ap.add_argument("runs", nargs="+", help="LABEL=BIN:FILE")
    a = ap.parse_args()
    print("| file | path | MB/s | mean coarser | loaded MB (originals) | loads | converge frames |")
    print("|---|---|---|---|---|---|---|")
    for run in a.runs:
        if "=" not in run or ":" not in run.split("=", 1)[1]:
            ap.error(f"{run!r}: a run is LABEL=BIN:FILE")
        label, rest = run.split("=", 1)
        binary, path = rest.split(":", 1)
        for p in a.paths.split(","):
            with tempfile.TemporaryDirectory() as out:
                res = subprocess.run(
                    [binary, "simulate", path, "--path", p, "--capacity", str(a.k), "--bandwidth", a.bandwidths,
                     "--latency", "0ms", "--policy", "paper", "--fps", "30", "--frames", "1200", "--out", out,
                     "--json"], capture_output=True, text=True)
            if res.returncode != 0:
                # atlastree's own error, not a traceback of the call.
                sys.exit(f"paging_cmp.py: {label}, path {p}: simulate failed (exit {res.returncode}):\n"
                         f"{res.stderr.strip()}")
            # Older binaries print a line before the JSON and the file list after it.
            rows, _ = json.JSONDecoder().raw_decode(res.stdout[res.stdout.index("["):])
            for r in rows:
                s = r["summary"]
                # `bandwidth` before session 28 (bytes per second either way).
                key = r["key"]
                rate = key.get("bandwidth_bytes_per_s", key.get("bandwidth"))
                mbs = "instant" if rate is None else f"{rate / 1e6:g}"
                orig = s.get("bytes_originals_total")
                orig = f" ({orig / 1e6:.1f})" if orig is not None else ""
                print(f"| {label} | {p} | {mbs} | {s['mean_coarser']:.4f} | {s['bytes_total'] / 1e6:.1f}{orig} | "
                      f"{s['loads']} | {' '.join(map(str, s['converge_frames']))} |")


if __name__ == "__main__":
    main()
