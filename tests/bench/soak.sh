#!/usr/bin/env bash
# Soak test of `ssdo serve` (a benchmark, not a CI test; docs/fuzzing.md).
#
#   tests/bench/soak.sh [--minutes N] [--clients K] [--ssdo PATH] [--keep]
#
# Runs `ssdo serve --watch --socket` for N minutes (default 10) under a steady mix of
#  - K socket client processes (default 3), each looping over: ping, stats, process by
#    path, process inline (with its sidecar), malformed JSON, an unknown op, a header over
#    the limit, an inline size over the limit, a truncated message, path escapes ("..",
#    a symlink out of the allowed root, an output outside --out);
#  - one dropper process putting a good frame (sidecar first, then the EXR by rename)
#    into the watched folder every 2 s and a corrupt one (truncated, random bytes, a
#    damaged OpenEXR conformance file) every 3 s;
# then drains the queue and checks:
#  - the service never died and stops with status 0 on SIGTERM;
#  - every valid request got the right answer (ok with the right size, or the right
#    error code for each invalid one; "busy" is counted, never expected here);
#  - every good dropped frame has its output and was computed exactly once (one "ok"
#    log line); every corrupt one has its error file and no output;
#  - resident memory (service + workers) is flat: start (after warm-up), peak, end;
#  - no file descriptor leaked: /proc/PID/fd of the service at start and at the end.
# Exit status 0 when every check passes. Figures are printed at the end.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
minutes=10 clients=3 ssdo=${SSDO_BINARY:-$root/build/ssdo} keep=0
while [ $# -gt 0 ]; do
  case $1 in
    --minutes) minutes=$2; shift 2 ;;
    --clients) clients=$2; shift 2 ;;
    --ssdo) ssdo=$2; shift 2 ;;
    --keep) keep=1; shift ;;
    *) echo "usage: $0 [--minutes N] [--clients K] [--ssdo PATH] [--keep]" >&2; exit 2 ;;
  esac
done
[ -x "$ssdo" ] || { echo "soak: $ssdo not found (build first: scripts/build.sh)" >&2; exit 2; }
command -v python3 >/dev/null || { echo "soak: python3 is needed for the socket clients" >&2; exit 2; }
command -v oiiotool >/dev/null || { echo "soak: oiiotool is needed to cut the test frame" >&2; exit 2; }

work=$(mktemp -d /tmp/ssdo-soak.XXXXXX)
serve_pid="" pids=()
cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
  if [ -n "$serve_pid" ] && kill -0 "$serve_pid" 2>/dev/null; then kill "$serve_pid"; wait "$serve_pid" || true; fi
  [ "$keep" = 1 ] && echo "soak: work folder kept: $work" || rm -rf "$work"
}
trap cleanup EXIT
mkdir -p "$work"/{watch,out,frames,corrupt,stop}

# A small good frame (a 160 x 120 crop of the Cornell dump: same camera, data window
# inside the display window) and its sidecar.
oiiotool "$root/examples/frames/cornell.exr" --crop 160x120+240+120 -o "$work/frames/good.exr"
cp "$root/examples/frames/cornell.camera.json" "$work/frames/good.camera.json"
ln -s /etc/passwd "$work/frames/escape.exr"
# Corrupt frames: truncations, random bytes, damaged conformance files when present.
head -c 3000 "$work/frames/good.exr" > "$work/corrupt/truncated_head.exr"
head -c $(( $(stat -c %s "$work/frames/good.exr") - 700 )) "$work/frames/good.exr" > "$work/corrupt/truncated_tail.exr"
head -c 20000 /dev/urandom > "$work/corrupt/random.exr"
printf 'v/1\001' > "$work/corrupt/magic_only.exr"
damaged=$root/../shared/exr-conformance/damaged
if [ -d "$damaged" ]; then
  for f in "$damaged"/clusterfuzz-testcase-minimized-openexr_exrcheck_fuzzer-4755804284649472 \
           "$damaged"/memory_DOS_2.1 "$damaged"/asan_heap-oob_504235_131_78b0e15388401193e1ee2ce20fb7f3b0_exr; do
    [ -f "$f" ] && cp "$f" "$work/corrupt/$(basename "$f").exr"
  done
fi

"$ssdo" serve --watch "$work/watch" -o "$work/out" --socket "$work/s" --allow "$work/frames" \
  --preset low --jobs 2 --queue 64 --frame-timeout 30 --client-timeout 10 \
  --max-request-bytes 65536 --max-inline-mb 4 > "$work/serve.log" 2>&1 &
serve_pid=$!
for _ in $(seq 100); do [ -S "$work/s" ] && break; sleep 0.1; done
[ -S "$work/s" ] || { echo "soak: the service did not start"; cat "$work/serve.log"; exit 1; }

rss_kb() {  # service + its workers
  local total=0 p
  for p in $serve_pid $(pgrep -P "$serve_pid" || true); do
    total=$(( total + $(awk '/VmRSS/ {print $2}' "/proc/$p/status" 2>/dev/null || echo 0) ))
  done
  echo "$total"
}
fds() { ls "/proc/$serve_pid/fd" | wc -l; }

# Socket clients.
cat > "$work/client.py" <<'EOF'
import json, os, random, socket, struct, sys, time
sock_path, frames, out, stop, seed = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4], int(sys.argv[5])
rnd = random.Random(seed)
good = open(os.path.join(frames, "good.exr"), "rb").read()
sidecar = json.load(open(os.path.join(frames, "good.camera.json")))
stats, examples = {}, []
def count(k):
    # "kind:outcome DETAILS": counted by kind and outcome; the first details are kept.
    key, _, details = k.partition(" ")
    stats[key] = stats.get(key, 0) + 1
    if details and len(examples) < 5: examples.append(k)
def conn():
    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM); s.settimeout(120); s.connect(sock_path); return s
def send(s, obj, extra=b""):
    body = obj if isinstance(obj, bytes) else json.dumps(obj).encode()
    s.sendall(struct.pack(">I", len(body)) + body + extra)
def recv_exact(s, n):
    b = b""
    while len(b) < n:
        c = s.recv(n - len(b))
        if not c: raise EOFError("closed after %d of %d bytes" % (len(b), n))
        b += c
    return b
def recv(s):
    r = json.loads(recv_exact(s, struct.unpack(">I", recv_exact(s, 4))[0]))
    data = recv_exact(s, r["inline_size"]) if r.get("ok") and "inline_size" in r else None
    return r, data
def expect_error(name, code, obj, extra=b""):
    s = conn()
    try:
        send(s, obj, extra); r, _ = recv(s)
        count(name + (":ok" if (not r["ok"] and r["code"] == code) else ":WRONG " + json.dumps(r)[:300]))
    except Exception as e:
        count(name + ":WRONG " + repr(e)[:200])
    finally: s.close()
def expect_frame(name, obj, extra=b""):
    s = conn()
    try:
        send(s, obj, extra); r, data = recv(s)
        if not r["ok"] and r.get("code") == "busy": count(name + ":busy"); return
        right = r["ok"] and r["width"] == 160 and r["height"] == 120
        if obj.get("reply") == "inline": right = right and data is not None and data[:4] == b"v/1\x01"
        elif right: right = os.path.isfile(r["output"]) and r["output"].startswith(out)
        count(name + (":ok" if right else ":WRONG " + json.dumps(r)[:200]))
    except Exception as e:
        count(name + ":WRONG " + repr(e)[:200])
    finally: s.close()
n = 0
while not os.path.exists(os.path.join(stop, "stop")):
    n += 1
    k = rnd.randrange(12)
    if k == 0:
        s = conn(); send(s, {"op": "ping", "id": n}); r, _ = recv(s); s.close()
        count("ping:" + ("ok" if r["ok"] and r["id"] == n else "WRONG"))
    elif k == 1:
        s = conn(); send(s, {"op": "stats"}); send(s, {"op": "ping"}); r1, _ = recv(s); r2, _ = recv(s); s.close()
        count("stats:" + ("ok" if r1["ok"] and "frames_done" in r1 and r2["ok"] else "WRONG"))
    elif k == 2:
        expect_frame("process_path", {"op": "process", "id": n, "input": os.path.join(frames, "good.exr"),
                                      "output": os.path.join(out, "c%d_%d.ssdo.exr" % (seed, n))})
    elif k == 3:
        expect_frame("process_inline", {"op": "process", "id": n, "inline_size": len(good), "name": "in%d" % seed,
                                        "sidecar": sidecar, "reply": "inline"}, good)
    elif k == 4: expect_error("malformed_json", "bad_request", b'{"op": "process", "input": ')
    elif k == 5: expect_error("unknown_op", "bad_request", {"op": "format_disk"})
    elif k == 6:
        s = conn()
        try:
            s.sendall(struct.pack(">I", 1 << 20) + b"{" * 1000); r, _ = recv(s)
            count("oversize_header:" + ("ok" if r["code"] == "too_large" else "WRONG"))
        except Exception as e: count("oversize_header:WRONG " + repr(e))
        finally: s.close()
    elif k == 7: expect_error("oversize_inline", "bad_request", {"op": "process", "inline_size": 64 << 20})
    elif k == 8:
        s = conn(); body = json.dumps({"op": "ping"}).encode()
        s.sendall(struct.pack(">I", len(body) + 10) + body); s.shutdown(socket.SHUT_WR)
        try: got = s.recv(4); count("truncated:" + ("ok" if got == b"" else "ok_answered"))
        except Exception as e: count("truncated:WRONG " + repr(e))
        s.close()
    elif k == 9: expect_error("escape_dotdot", "forbidden", {"op": "process", "input": frames + "/../../../etc/passwd"})
    elif k == 10: expect_error("escape_symlink", "forbidden", {"op": "process", "input": os.path.join(frames, "escape.exr")})
    else: expect_error("escape_output", "forbidden", {"op": "process", "input": os.path.join(frames, "good.exr"),
                                                   "output": "/tmp/ssdo-soak-escape.exr"})
    time.sleep(rnd.uniform(0.0, 0.2))
json.dump({"counts": stats, "examples": examples}, open(os.path.join(stop, "client%d.json" % seed), "w"))
EOF

# The dropper: good frames every 2 s, corrupt ones every 3 s (names never reused).
cat > "$work/dropper.sh" <<'EOF'
#!/usr/bin/env bash
work=$1 i=0
mapfile -t corrupt < <(ls "$work/corrupt")
while [ ! -e "$work/stop/stop" ]; do
  i=$((i + 1))
  name=good_$(printf %05d $i)
  cp "$work/frames/good.camera.json" "$work/watch/$name.camera.json"
  cp "$work/frames/good.exr" "$work/watch/.$name.tmp" && mv "$work/watch/.$name.tmp" "$work/watch/$name.exr"
  echo "$name" >> "$work/dropped_good.txt"
  if [ $((i % 3)) -eq 0 ]; then
    c=${corrupt[$(( (i / 3) % ${#corrupt[@]} ))]}
    bad=bad_$(printf %05d $i)_${c%.exr}
    cp "$work/corrupt/$c" "$work/watch/.$bad.tmp" && mv "$work/watch/.$bad.tmp" "$work/watch/$bad.exr"
    echo "$bad" >> "$work/dropped_bad.txt"
  fi
  sleep 2
done
EOF

sleep 5  # warm-up: workers started
rss_start=$(rss_kb) fd_start=$(fds) rss_peak=$rss_start
for c in $(seq "$clients"); do
  python3 "$work/client.py" "$work/s" "$work/frames" "$work/out" "$work/stop" "$c" & pids+=($!)
done
bash "$work/dropper.sh" "$work" & pids+=($!)
echo "soak: $minutes min, $clients clients + 1 dropper; service pid $serve_pid; RSS ${rss_start} KiB, $fd_start fds at start"

end=$(( $(date +%s) + minutes * 60 )) died=0
while [ "$(date +%s)" -lt "$end" ]; do
  sleep 5
  if ! kill -0 "$serve_pid" 2>/dev/null; then died=1; break; fi
  r=$(rss_kb); [ "$r" -gt "$rss_peak" ] && rss_peak=$r
done
touch "$work/stop/stop"
for p in "${pids[@]}"; do wait "$p" || true; done
pids=()

# Drain: every dropped frame answered (output or error file), queue empty.
fail=0
if [ $died = 1 ]; then echo "soak: FAIL: the service died"; fail=1; fi
for _ in $(seq 600); do
  [ $died = 1 ] && break
  pending=0
  while read -r n; do [ -e "$work/out/$n.ssdo.exr" ] || pending=$((pending + 1)); done < "$work/dropped_good.txt"
  while read -r n; do [ -e "$work/out/$n.error.json" ] || pending=$((pending + 1)); done < <(cat "$work/dropped_bad.txt" 2>/dev/null)
  [ $pending -eq 0 ] && break
  sleep 1
done
sleep 2
rss_end=$(rss_kb) fd_end=$(fds)
[ "$rss_end" -gt "$rss_peak" ] && rss_peak=$rss_end

good_n=$(wc -l < "$work/dropped_good.txt") bad_n=$(cat "$work/dropped_bad.txt" 2>/dev/null | wc -l)
missing=0 twice=0 bad_wrong=0
while read -r n; do
  [ -e "$work/out/$n.ssdo.exr" ] || { missing=$((missing + 1)); echo "soak: no output for $n"; }
  k=$(grep -c "^ok $work/watch/$n.exr -> " "$work/serve.log" || true)
  [ "$k" = 1 ] || { twice=$((twice + 1)); echo "soak: $n computed $k times"; }
done < "$work/dropped_good.txt"
while read -r n; do
  if [ ! -e "$work/out/$n.error.json" ] || [ -e "$work/out/$n.ssdo.exr" ]; then
    bad_wrong=$((bad_wrong + 1)); echo "soak: corrupt $n: no error file, or an output"
  fi
done < <(cat "$work/dropped_bad.txt" 2>/dev/null)

kill -TERM "$serve_pid"; status=0; wait "$serve_pid" || status=$?; serve_pid=""

python3 - "$work/stop" <<'EOF'
import glob, json, sys
total, examples = {}, []
for f in glob.glob(sys.argv[1] + "/client*.json"):
    r = json.load(open(f))
    examples += r["examples"]
    for k, v in r["counts"].items(): total[k] = total.get(k, 0) + v
for k in sorted(total): print("  %-28s %d" % (k, total[k]))
for e in examples[:5]: print("  e.g. " + e[:300])
open(sys.argv[1] + "/wrong", "w").write(str(sum(v for k, v in total.items() if k.endswith(":WRONG"))))
EOF
wrong=$(cat "$work/stop/wrong")
echo "soak: requests by kind and outcome (above); wrong answers: $wrong"
echo "soak: dropped $good_n good frames (missing $missing, not exactly once $twice), $bad_n corrupt (wrong $bad_wrong)"
echo "soak: RSS service+workers KiB: start $rss_start, peak $rss_peak, end $rss_end"
echo "soak: service fds: start $fd_start, end $fd_end"
echo "soak: $(grep -c '^ok ' "$work/serve.log") frames ok, $(grep -c '^FAILED ' "$work/serve.log") failed in the log; exit status $status"
[ "$wrong" = 0 ] || fail=1
[ $missing = 0 ] && [ $twice = 0 ] && [ $bad_wrong = 0 ] || fail=1
[ "$fd_end" -le "$fd_start" ] || { echo "soak: FAIL: file descriptors leaked"; fail=1; }
# Flat: the end within 32 MiB or 25 % of the start (allocator caches, log buffers).
if [ $(( rss_end - rss_start )) -gt $(( rss_start / 4 > 32768 ? rss_start / 4 : 32768 )) ]; then
  echo "soak: FAIL: resident memory grew"; fail=1
fi
[ $status = 0 ] || { echo "soak: FAIL: ssdo serve exited with $status"; fail=1; }
[ $fail = 0 ] && echo "soak: PASS" || echo "soak: FAIL"
exit $fail
