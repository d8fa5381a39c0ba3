#!/usr/bin/env python3
"""Checks tools/scaleout/k8s/build-job.yaml without a cluster: valid YAML, the four objects, an Indexed shard
Job whose completions equal ATLASTREE_SHARD_COUNT, `--shard auto`, a plan Job whose command is the shards' with
`--shard plan`, every argument a string, one ReadWriteMany claim mounted by every Job, and the same build output
path in the shard command and the merge command.
Needs PyYAML. Exit status 0 when all hold."""

import sys
from pathlib import Path

import yaml

path = Path(sys.argv[1] if len(sys.argv) > 1 else Path(__file__).with_name("build-job.yaml"))
docs = [d for d in yaml.safe_load_all(path.read_text()) if d]
by_step = {d["metadata"]["labels"]["atlastree/step"]: d for d in docs}
assert sorted(by_step) == ["merge", "plan", "shards", "volume"], f"steps: {sorted(by_step)}"
pvc, plan, shards, merge = by_step["volume"], by_step["plan"], by_step["shards"], by_step["merge"]
assert pvc["kind"] == "PersistentVolumeClaim" and "ReadWriteMany" in pvc["spec"]["accessModes"]
assert plan["kind"] == shards["kind"] == merge["kind"] == "Job"

spec = shards["spec"]
shard = spec["template"]["spec"]["containers"][0]
env = {e["name"]: e["value"] for e in shard["env"]}
assert spec["completionMode"] == "Indexed", "the shard Job must be Indexed (JOB_COMPLETION_INDEX)"
assert int(env["ATLASTREE_SHARD_COUNT"]) == spec["completions"], "ATLASTREE_SHARD_COUNT != completions"
assert spec["parallelism"] <= spec["completions"]
cmd = shard["command"]
merge_cmd = merge["spec"]["template"]["spec"]["containers"][0]["command"]
plan_cmd = plan["spec"]["template"]["spec"]["containers"][0]["command"]
at = cmd.index("--shard") + 1
assert plan_cmd == cmd[:at] + ["plan"] + cmd[at + 1 :], f"plan {plan_cmd} is not the shards' {cmd} with --shard plan"
for c in (cmd, merge_cmd, plan_cmd):
    assert all(isinstance(a, str) for a in c), f"non-string argument in {c} (quote numbers)"
assert cmd[1] == "build" and cmd[cmd.index("--shard") + 1] == "auto"
out = cmd[cmd.index("-o") + 1]
assert merge_cmd[1:] == ["merge", out], f"merge {merge_cmd[1:]} is not of the shards' output {out}"
for job in (plan, shards, merge):
    t = job["spec"]["template"]["spec"]
    assert t["restartPolicy"] == "Never"
    assert {v["persistentVolumeClaim"]["claimName"] for v in t["volumes"]} == {pvc["metadata"]["name"]}
print(f"ok {path}: plan Job, Indexed Job of {spec['completions']} shards (parallelism {spec['parallelism']}), "
      f"merge of {out}, ReadWriteMany claim {pvc['metadata']['name']}")
