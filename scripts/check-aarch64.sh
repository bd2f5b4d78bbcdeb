#!/usr/bin/env bash
# Compiles every source of the core, kernels, formats and service layers for aarch64 with
# Debian's cross compiler (g++-aarch64-linux-gnu), the flags of the host build's
# compile_commands.json: Highway then builds the NEON target of each dispatched file. A
# compile check, not a link (the Arm libraries are not installed) nor a run.
#   scripts/check-aarch64.sh [BUILD_DIR]     (default build/, configured by scripts/build.sh)
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir="${1:-build}"
if ! command -v aarch64-linux-gnu-g++ >/dev/null; then
  echo "check-aarch64: needs aarch64-linux-gnu-g++ (apt-get install g++-aarch64-linux-gnu)" >&2
  exit 2
fi
if [ ! -f "$build_dir/compile_commands.json" ]; then
  echo "check-aarch64: no $build_dir/compile_commands.json (configure with scripts/build.sh first)" >&2
  exit 2
fi
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
python3 - "$build_dir/compile_commands.json" "$out" <<'PY'
import json, os, shlex, subprocess, sys
from concurrent.futures import ThreadPoolExecutor
entries = [e for e in json.load(open(sys.argv[1]))
           if any(f"/{layer}/" in e["file"] for layer in ("core", "kernels", "formats", "service"))]
def compile_one(e):
    args = shlex.split(e["command"])
    # x86-only assembler padding (formats/CMakeLists.txt adds it where the host supports it).
    args = ["aarch64-linux-gnu-g++"] + [a for a in args[1:] if a != "-Wa,-mbranches-within-32B-boundaries"]
    args[args.index("-o") + 1] = os.path.join(sys.argv[2], os.path.basename(e["file"]) + ".o")
    r = subprocess.run(args, cwd=e["directory"], capture_output=True, text=True)
    return e["file"], r.returncode, r.stderr
failed = 0
with ThreadPoolExecutor(os.cpu_count() or 2) as pool:
    for path, rc, err in pool.map(compile_one, entries):
        if rc != 0 or "warning" in err:
            print(f"{path}:\n{err}", file=sys.stderr)
        failed += rc != 0
print(f"check-aarch64: {len(entries) - failed} of {len(entries)} sources compile for aarch64")
sys.exit(1 if failed else 0)
PY
