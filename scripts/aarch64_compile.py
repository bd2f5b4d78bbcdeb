#!/usr/bin/env python3
"""Compiles sources of the host build for aarch64 with Debian's cross compiler.

    aarch64_compile.py COMPILE_COMMANDS OUT_DIR LAYER...

Every entry of the host build's compile_commands.json whose file lies under one of the
LAYER folders (e.g. core, kernels, tests/unit/kernels) is compiled with
aarch64-linux-gnu-g++ and the host's flags (Highway then builds the NEON target of each
dispatched file), into OUT_DIR/<path with / as _>.o, on every core. Prints each failing or
warning source's messages and a count; exits 1 when a source failed.
Used by scripts/check-aarch64.sh and scripts/test-aarch64.sh.
"""
import json
import os
import shlex
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

commands, out_dir, layers = sys.argv[1], sys.argv[2], sys.argv[3:]
entries = [e for e in json.load(open(commands)) if any(f"/{layer}/" in e["file"] for layer in layers)]


def compile_one(e):
    args = shlex.split(e["command"])
    # x86-only assembler padding (formats/CMakeLists.txt adds it where the host supports it).
    args = ["aarch64-linux-gnu-g++"] + [a for a in args[1:] if a != "-Wa,-mbranches-within-32B-boundaries"]
    args[args.index("-o") + 1] = os.path.join(out_dir, e["file"].replace("/", "_") + ".o")
    r = subprocess.run(args, cwd=e["directory"], capture_output=True, text=True)
    return e["file"], r.returncode, r.stderr


failed = 0
with ThreadPoolExecutor(os.cpu_count() or 2) as pool:
    for path, rc, err in pool.map(compile_one, entries):
        if rc != 0 or "warning" in err:
            print(f"{path}:\n{err}", file=sys.stderr)
        failed += rc != 0
print(f"{len(entries) - failed} of {len(entries)} sources compile for aarch64")
sys.exit(1 if failed else 0)
