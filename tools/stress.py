"""The long robustness run (make stress): PYOPENCL_RT_STRESS=1 pytest tests/test_robustness.py,
then a JSON and markdown summary of the per-test lines it prints (escape counts per mesh,
transform and device; spawn failure counts; invariance z-scores) under docs/bench/."""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> int:
    out_dir = ROOT / "docs" / "bench"
    out_dir.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ, PYOPENCL_RT_STRESS="1")
    cmd = [sys.executable, "-m", "pytest", "tests/test_robustness.py", "-q", "-s", "-rxXf", "-p", "no:cacheprovider"]
    t0 = time.time()
    proc = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True)
    seconds = time.time() - t0
    sys.stdout.write(proc.stdout[-20000:])
    sys.stderr.write(proc.stderr[-5000:])
    lines = proc.stdout.splitlines()
    measured = [ln.strip() for ln in lines if re.match(r"\s*(watertight|spawn|invariance) ", ln.strip())]
    outcome = [ln for ln in lines if re.match(r"^(FAILED|XFAIL|XPASS|ERROR)", ln)]
    summary = [ln for ln in lines if re.search(r"\d+ (passed|failed)", ln)]
    result = {"command": "PYOPENCL_RT_STRESS=1 " + " ".join(cmd[1:]), "seconds": round(seconds, 1),
              "returncode": proc.returncode, "summary": summary[-1] if summary else "",
              "measured": measured, "outcomes": outcome}
    (out_dir / "stress.json").write_text(json.dumps(result, indent=2) + "\n")
    md = ["# make stress", "", f"`{result['command']}`: {result['summary']} ({seconds:.0f} s)", "", "```"]
    md += measured + outcome + ["```", ""]
    (out_dir / "stress.md").write_text("\n".join(md))
    return proc.returncode


if __name__ == "__main__":
    sys.exit(main())
