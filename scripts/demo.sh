#!/usr/bin/env bash
# Build and run the main job on a bundled example: the CLI evaluates two pressed
# disks (examples/two_disks.json) and prints the summary and the active contacts;
# then, when the daemon is built, it is started, queried once with the same
# scene, and left running in the foreground until Ctrl-C (scripts/serve-demo.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
NTS_BUILD_DIR=build bash scripts/build.sh
echo "== ntscontact examples/two_disks.json (summary and active contacts)"
./build/bin/ntscontact --outputs energy,virial,contacts examples/two_disks.json |
  .venv/bin/python -c '
import json, sys
r = json.load(sys.stdin)
s = r["summary"]
print("bodies %d, surface nodes %d, active contacts %d, energy %.6g, max penetration %.3g"
      % (s["bodies"], s["surface_nodes"], s["contacts"], s["energy"], s["max_penetration"]))
print("virial xx %.6g yy %.6g xy %.6g" % (s["virial"]["xx"], s["virial"]["yy"], s["virial"]["xy"]))
print("%-8s %-5s %-8s %-8s %-12s %s" % ("slave", "node", "master", "kind", "gap", "force on slave"))  # (+ 0.0: no "-0")
for c in r.get("contacts", []):
    print("%-8s %-5d %-8s %-8s %-12.4e (%+.4e, %+.4e)" % (c["slave"]["body"], c["slave"]["node"],
          c["master"]["body"], c["master"]["kind"], c["gap"], c["force"][0] + 0.0, c["force"][1] + 0.0))
'
if [ -x build/bin/ntscontactd ] && [ -f scripts/serve-demo.sh ] && [ -z "${NTS_DEMO_NO_SERVER:-}" ]; then
  echo "== the same scene through the HTTP service"
  exec bash scripts/serve-demo.sh
fi
