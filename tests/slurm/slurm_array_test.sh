#!/usr/bin/env bash
# The Slurm job array of examples/slurm/ on a real one-node Slurm cluster on localhost.
#
#   tests/slurm/slurm_array_test.sh SSDO_BINARY SOURCE_DIR
#
# Installs Debian's slurmctld, slurmd, slurm-client and munge when missing (root only),
# starts munged, slurmctld and slurmd with their own key, ports, state and logs in a temp
# folder, and then:
#   1. one `ssdo process` over 24 frames (the reference outputs and wall time),
#   2. the 24 frames as a 4-task array job (sbatch --wait): every output written exactly
#      once, by the task whose chunk holds the frame, identical to the reference,
#   3. the array again, task 3 cancelled (scancel) in the middle of its chunk, then
#      requeued (scontrol requeue): all 24 outputs, identical to the reference, each
#      written once, no temp files,
#   4. a rerun of one finished task (sbatch --array=2): every frame skipped, exit 0.
# Daemons and jobs are stopped on every exit path. Exit 77 (CTest's SKIP_RETURN_CODE)
# with the reason when the machine cannot run a cluster. SSDO_SLURM_KEEP=1 keeps the temp
# folder for a look at the logs.
set -uo pipefail

SKIP=77
ssdo=${1:?usage: $0 SSDO_BINARY SOURCE_DIR}
src=${2:?usage: $0 SSDO_BINARY SOURCE_DIR}
ssdo=$(readlink -f "$ssdo")
src=$(readlink -f "$src")
job_script="$src/examples/slurm/ssdo_array.sbatch"
export PATH="$PATH:/usr/sbin:/sbin"

say() { echo "[slurm test $(date +%T)] $*"; }
skip() { echo "SKIP: $*"; exit $SKIP; }

# ---------------------------------------------------------------------------------------
# Slurm and munge, installed when missing
# ---------------------------------------------------------------------------------------
have_cluster_tools() {
  local t
  for t in munged munge slurmctld slurmd sbatch squeue scontrol scancel sinfo; do
    command -v "$t" > /dev/null || return 1
  done
}

install_cluster_tools() {
  [ "$(id -u)" = 0 ] || skip "Slurm/munge are not installed and installing them needs root"
  command -v apt-get > /dev/null || skip "Slurm/munge are not installed and there is no apt-get"
  say "installing slurmctld slurmd slurm-client munge (apt-get)"
  # No service may start from the packages' scripts: the test runs its own daemons.
  local policy=/usr/sbin/policy-rc.d made_policy=0
  if [ ! -e "$policy" ]; then
    printf '#!/bin/sh\nexit 101\n' > "$policy" && chmod 755 "$policy" && made_policy=1
  fi
  local pkgs=(slurmctld slurmd slurm-client munge) ok=0
  export DEBIAN_FRONTEND=noninteractive
  if timeout 600 apt-get install -y --no-install-recommends "${pkgs[@]}" > "$install_log" 2>&1; then
    ok=1
  elif timeout 300 apt-get update >> "$install_log" 2>&1 &&
       timeout 600 apt-get install -y --no-install-recommends "${pkgs[@]}" >> "$install_log" 2>&1; then
    ok=1
  fi
  [ $made_policy = 1 ] && rm -f "$policy"
  if [ $ok != 1 ]; then
    tail -5 "$install_log"
    skip "apt-get could not install ${pkgs[*]} (log above)"
  fi
  have_cluster_tools || skip "installed ${pkgs[*]} but a command is still missing"
}

install_log=$(mktemp /tmp/ssdo-slurm-apt.XXXXXX)
if ! have_cluster_tools; then install_cluster_tools; fi
rm -f "$install_log"
[ "$(id -u)" = 0 ] || skip "slurmd must run as root (this test runs a cluster with SlurmUser=root)"
[ -x "$ssdo" ] || { echo "FAIL: no ssdo binary at $ssdo"; exit 1; }
[ -f "$job_script" ] || { echo "FAIL: no job script at $job_script"; exit 1; }

# ---------------------------------------------------------------------------------------
# The cluster: munged + slurmctld + slurmd, all in $T, stopped by the EXIT trap
# ---------------------------------------------------------------------------------------
T=$(mktemp -d /tmp/ssdo-slurm.XXXXXX)
chmod 755 "$T"
mkdir -p "$T/munge-key" "$T/munge" "$T/etc" "$T/state" "$T/spool" "$T/log" "$T/jobs"
chmod 700 "$T/munge-key"
daemon_pids=()

# Kills whatever the cluster in folder $1 still runs: slurmctld, slurmd, slurmstepd and job
# processes carry its SLURM_CONF, munged its socket path.
kill_leftovers() {
  local dir=$1 e pid
  for e in /proc/[0-9]*/environ; do
    pid=${e#/proc/}
    pid=${pid%/environ}
    [ "$pid" = $$ ] || [ "$pid" = "$BASHPID" ] && continue
    if { tr '\0' '\n' < "$e"; } 2> /dev/null | grep -qxF "SLURM_CONF=$dir/etc/slurm.conf" ||
       { tr '\0' '\n' < "/proc/$pid/cmdline"; } 2> /dev/null | grep -qxF -- "--socket=$dir/munge/munge.socket"; then
      echo "[slurm test] killing leftover process $pid: $({ tr '\0' ' ' < "/proc/$pid/cmdline"; } 2> /dev/null)"
      kill -KILL "$pid" 2> /dev/null
    fi
  done
}

# A detached watchdog for the case no trap can handle (this script killed outright, e.g.
# by a CTest timeout): once this script is gone, it ends what the cluster left running.
(
  setsid bash -c "$(declare -f kill_leftovers)
    while kill -0 $$ 2> /dev/null; do sleep 2; done
    kill_leftovers '$T'
    [ '${SSDO_SLURM_KEEP:-0}' = 1 ] || rm -rf '$T'" > /dev/null 2>&1 < /dev/null &
)

stop_all() {
  local status=$?
  trap - EXIT INT TERM
  if [ -n "${SLURM_CONF:-}" ] && [ ${#daemon_pids[@]} -gt 0 ]; then
    # Jobs first, while slurmctld and slurmd can still end them.
    local jobs
    jobs=$(timeout 10 squeue -h -o %A 2> /dev/null | sort -u)
    if [ -n "$jobs" ]; then
      # shellcheck disable=SC2086
      timeout 10 scancel $jobs 2> /dev/null
      for _ in $(seq 1 30); do
        [ -z "$(timeout 5 squeue -h 2> /dev/null)" ] && break
        sleep 0.5
      done
    fi
  fi
  local pid
  for pid in "${daemon_pids[@]}"; do kill -TERM "$pid" 2> /dev/null; done
  for _ in $(seq 1 50); do
    local alive=0
    for pid in "${daemon_pids[@]}"; do kill -0 "$pid" 2> /dev/null && alive=1; done
    [ $alive = 0 ] && break
    sleep 0.2
  done
  for pid in "${daemon_pids[@]}"; do kill -KILL "$pid" 2> /dev/null; done
  export -n SLURM_CONF  # from here on, no child of this script looks like the cluster's
  kill_leftovers "$T"
  for pid in "${daemon_pids[@]}"; do wait "$pid" 2> /dev/null; done
  if [ $status != 0 ] && [ $status != $SKIP ]; then
    say "logs of the failed run:"
    local f
    for f in "$T"/log/*.log "$T"/jobs/*.log; do
      [ -f "$f" ] || continue
      echo "----- $f (last 30 lines)"
      tail -30 "$f"
    done
  fi
  if [ "${SSDO_SLURM_KEEP:-0}" = 1 ]; then
    say "kept $T"
  else
    rm -rf "$T"
  fi
  exit $status
}
trap stop_all EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

fail() {
  echo "FAIL: $*"
  exit 1
}

# A free TCP port pair above 10000 (slurmctld, slurmd).
port_in_use() { (exec 3<> "/dev/tcp/127.0.0.1/$1") 2> /dev/null; }
for _ in $(seq 1 50); do
  ctld_port=$((20000 + RANDOM % 20000))
  slurmd_port=$((ctld_port + 1))
  port_in_use $ctld_port || port_in_use $slurmd_port || break
done

# munged: a fresh key and socket of its own.
dd if=/dev/urandom of="$T/munge-key/munge.key" bs=1024 count=1 status=none
chmod 400 "$T/munge-key/munge.key"
munge_socket="$T/munge/munge.socket"
munged --force --socket="$munge_socket" --key-file="$T/munge-key/munge.key" \
  --pid-file="$T/munge/munged.pid" --log-file="$T/log/munged.log" --seed-file="$T/munge/seed" ||
  fail "munged did not start (log: $(tail -3 "$T/log/munged.log" 2> /dev/null))"
daemon_pids+=("$(cat "$T/munge/munged.pid")")
munge -n -S "$munge_socket" | unmunge -S "$munge_socket" > /dev/null || fail "munge does not work"

# slurm.conf: this host as controller and only node, with its real CPUs and memory.
node_line=$(slurmd -C | head -1)  # NodeName=HOST CPUs=.. Boards=.. ... RealMemory=..
node=$(sed -n 's/^NodeName=\([^ ]*\).*/\1/p' <<< "$node_line")
[ -n "$node" ] || fail "slurmd -C did not describe this node: $node_line"
cpus=$(sed -n 's/.* CPUs=\([0-9]*\).*/\1/p' <<< "$node_line")
export SLURM_CONF="$T/etc/slurm.conf"
: > "$T/etc/plugstack.conf"
cat > "$SLURM_CONF" << EOF
ClusterName=ssdotest
SlurmctldHost=$node(127.0.0.1)
SlurmUser=root
SlurmdUser=root
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
AuthType=auth/munge
CredType=cred/munge
# cred_expire also delays a requeued job's restart (default 120 s)
AuthInfo=socket=$munge_socket,cred_expire=10
StateSaveLocation=$T/state
SlurmdSpoolDir=$T/spool
SlurmctldPidFile=$T/slurmctld.pid
SlurmdPidFile=$T/slurmd.pid
SlurmctldLogFile=$T/log/slurmctld.log
SlurmdLogFile=$T/log/slurmd.log
PlugStackConfig=$T/etc/plugstack.conf
MailProg=/bin/true
# No cgroups in a sandbox: processes tracked by parent pid, tasks bound by sched_setaffinity
ProctrackType=proctrack/linuxproc
TaskPlugin=task/affinity
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
SchedulerType=sched/backfill
# Pending jobs (a requeued task, once its begin time has passed) are scheduled within a
# second or two instead of at the next pass of the default 60 s and 30 s loops.
SchedulerParameters=sched_interval=2,bf_interval=1
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
KillWait=5
MinJobAge=600
$node_line NodeAddr=127.0.0.1 State=UNKNOWN
PartitionName=farm Nodes=ALL Default=YES MaxTime=INFINITE State=UP
EOF

slurmctld -D -i > "$T/log/slurmctld.out" 2>&1 &
daemon_pids+=($!)
slurmd -D -N "$node" > "$T/log/slurmd.out" 2>&1 &
daemon_pids+=($!)
state=""
for _ in $(seq 1 60); do
  state=$(timeout 5 sinfo -h -N -n "$node" -o %t 2> /dev/null)
  [ "$state" = idle ] && break
  sleep 0.5
done
[ "$state" = idle ] || fail "the node did not come up idle (state: '${state:-none}')"
say "cluster up: node $node, $cpus CPUs, slurmctld port $ctld_port, in $T"

# ---------------------------------------------------------------------------------------
# Frames: a shot of 24 copies of the example frames (with their camera sidecars)
# ---------------------------------------------------------------------------------------
# 24 frames in 4 tasks: 6 frames per task, so a task cancelled after its first output
# still has frames left to compute when it is requeued (a frame takes 0.3-0.5 s on one
# core, and a cancelled task finishes the frame in flight before it ends).
shot_frames=24
frames="$T/frames"
mkdir -p "$frames"
for i in $(seq 1 $shot_frames); do
  n=$(printf %04d "$i")
  name=cornell
  [ $((i % 2)) = 0 ] && name=greeble
  cp "$src/examples/frames/$name.exr" "$frames/shot.$n.exr"
  cp "$src/examples/frames/$name.camera.json" "$frames/shot.$n.camera.json"
done
pattern="$frames/shot.####.exr"
# gtao high, the slowest GTAO preset. Without compression, so that outputs of different
# processes compare byte for byte (zip's streams may differ for the same samples:
# docs/usage.md, "Render farms").
options=(--frames 1-$shot_frames --method gtao --preset high --compression none)
chunks=4
export SSDO="$ssdo"

now() { date +%s.%N; }
seconds() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.1f", b - a }'; }

# Frames (numbers) whose output line says ok in the given logs, one per line, sorted.
ok_frames() { cat "$@" 2> /dev/null | sed -n 's/.*shot\.\([0-9]\{4\}\)\.ssdo\.exr: ok.*/\1/p' | sort; }

# The chunk (1..N) of frame number f (1..shot_frames) by chunk_slice's rule: chunk c holds
# indices [floor((c-1) F / N), floor(c F / N)).
chunk_of() {
  local i=$(($1 - 1)) c
  for c in $(seq 1 $chunks); do
    [ $i -ge $(($shot_frames * (c - 1) / chunks)) ] && [ $i -lt $(($shot_frames * c / chunks)) ] && { echo $c; return; }
  done
}

# Every output is there, nothing else is (no temp or error files), and each output is
# byte-identical to the reference.
check_outputs() {
  local dir=$1 what=$2 i n extra
  for i in $(seq 1 $shot_frames); do
    n=$(printf %04d "$i")
    [ -f "$dir/shot.$n.ssdo.exr" ] || fail "$what: no output for frame $n"
    cmp -s "$dir/shot.$n.ssdo.exr" "$T/out-single/shot.$n.ssdo.exr" ||
      fail "$what: output of frame $n differs from the single-process output"
  done
  extra=$(cd "$dir" && ls -A | grep -v '^shot\.[0-9]\{4\}\.ssdo\.exr$')
  [ -z "$extra" ] || fail "$what: unexpected files in the output folder: $extra"
}

# State of one array task, e.g. COMPLETED, and its exit code (e.g. 0:0).
task_field() { timeout 10 scontrol -o show job "$1" 2> /dev/null | sed -n "s/.* $2=\([^ ]*\).*/\1/p" | head -1; }

# Seconds from an array job's submission to its last task's end, from slurmctld's log
# (millisecond timestamps): "_slurm_rpc_submit_batch_job: JobId=J" .. the last
# "_job_complete: JobId=J_I(...) done".
job_span() {
  local stamps
  stamps=$(grep -E "(_slurm_rpc_submit_batch_job: JobId=$1 |_job_complete: JobId=$1_[0-9]+\([0-9]+\) done)" \
    "$T/log/slurmctld.log" | sed -n 's/^\[\([^]]*\)\].*/\1/p')
  [ -n "$stamps" ] || { echo "?"; return; }
  awk -v a="$(date -d "$(head -1 <<< "$stamps")" +%s.%N)" -v b="$(date -d "$(tail -1 <<< "$stamps")" +%s.%N)" \
    'BEGIN { printf "%.1f", b - a }'
}

# ---------------------------------------------------------------------------------------
# 1. One ssdo process over the shot: reference outputs and wall time
# ---------------------------------------------------------------------------------------
say "1. one ssdo process over $shot_frames frames"
t0=$(now)
"$ssdo" process "$pattern" "${options[@]}" -o "$T/out-single" > "$T/log/single.log" 2>&1 ||
  fail "ssdo process over the $shot_frames frames failed: $(tail -5 "$T/log/single.log")"
t_single=$(seconds "$t0" "$(now)")
[ "$(ok_frames "$T/log/single.log" | wc -l)" = $shot_frames ] || fail "the single process did not compute $shot_frames frames"
say "   $t_single s"

# ---------------------------------------------------------------------------------------
# 2. The array job: 4 tasks, 1 CPU each
# ---------------------------------------------------------------------------------------
say "2. array job of $chunks tasks over the $shot_frames frames (sbatch --wait)"
t0=$(now)
job1=$(sbatch --wait --parsable --array=1-$chunks --cpus-per-task=1 --chdir="$T" \
  --output="$T/jobs/run1_%a.log" "$job_script" $chunks "$T/out-array" "$pattern" "${options[@]}")
rc=$?
t_array=$(seconds "$t0" "$(now)")
job1=${job1%%;*}
[ $rc = 0 ] || fail "array job $job1 exited $rc"
span1=$(job_span "$job1")
say "   job $job1: $span1 s from submission to the last task's end, $t_array s until sbatch --wait returned"
for c in $(seq 1 $chunks); do
  [ "$(task_field "${job1}_$c" JobState)" = COMPLETED ] || fail "task $c of job $job1 did not complete"
done
check_outputs "$T/out-array" "array job"
# Exactly once, and by the task whose chunk holds the frame.
[ "$(ok_frames "$T"/jobs/run1_*.log | uniq -d)" = "" ] || fail "a frame was computed twice: $(ok_frames "$T"/jobs/run1_*.log | uniq -d)"
[ "$(ok_frames "$T"/jobs/run1_*.log | wc -l)" = $shot_frames ] || fail "the array job did not compute each of the $shot_frames frames once"
for i in $(seq 1 $shot_frames); do
  n=$(printf %04d "$i")
  c=$(chunk_of "$i")
  ok_frames "$T/jobs/run1_$c.log" | grep -qx "$n" || fail "frame $n was not computed by task $c"
done
say "   $shot_frames outputs, each computed once by the task of its chunk, identical to the single process"

# ---------------------------------------------------------------------------------------
# 3. Cancel task 3 in the middle of its chunk, requeue it
# ---------------------------------------------------------------------------------------
victim=3
first=$(($shot_frames * (victim - 1) / chunks + 1))
last=$(($shot_frames * victim / chunks))
say "3. array job again; task $victim (frames $first-$last) cancelled mid-chunk, then requeued"
out="$T/out-requeue"
job2=$(sbatch --parsable --array=1-$chunks --cpus-per-task=1 --chdir="$T" \
  --output="$T/jobs/run2_%a.log" "$job_script" $chunks "$out" "$pattern" "${options[@]}") ||
  fail "sbatch failed"
job2=${job2%%;*}
first_out="$out/shot.$(printf %04d $first).ssdo.exr"
deadline=$((SECONDS + 180))
while [ ! -f "$first_out" ]; do
  [ $SECONDS -lt $deadline ] || fail "task $victim did not write its first frame within 180 s"
  sleep 0.1
done
[ "$(task_field "${job2}_$victim" JobState)" = RUNNING ] || fail "task $victim is not running after its first frame"
scancel "${job2}_$victim" || fail "scancel ${job2}_$victim failed"
done_at_cancel=$(for i in $(seq $first $last); do [ -f "$out/shot.$(printf %04d "$i").ssdo.exr" ] && echo; done | wc -l)
say "   cancelled task $victim with $done_at_cancel of its $((last - first + 1)) frames written"
deadline=$((SECONDS + 180))
while [ -n "$(timeout 10 squeue -h -j "$job2" 2> /dev/null)" ]; do
  [ $SECONDS -lt $deadline ] || fail "job $job2 did not end within 180 s"
  sleep 0.5
done
[ "$(task_field "${job2}_$victim" JobState)" = CANCELLED ] ||
  fail "task $victim is $(task_field "${job2}_$victim" JobState), not CANCELLED"
missing=0
for i in $(seq 1 $shot_frames); do
  n=$(printf %04d "$i")
  if [ -f "$out/shot.$n.ssdo.exr" ]; then
    # Whatever is at an output's final path is complete (temp file + rename).
    cmp -s "$out/shot.$n.ssdo.exr" "$T/out-single/shot.$n.ssdo.exr" || fail "frame $n: a partial or wrong output after the cancel"
  else
    missing=$((missing + 1))
    [ "$(chunk_of "$i")" = $victim ] || fail "frame $n (not of task $victim) has no output"
  fi
done
[ $missing -gt 0 ] || fail "task $victim finished its chunk before it was cancelled: nothing was interrupted"
temps=$(cd "$out" && ls -A | grep -c '\.tmp-' || true)
say "   after the cancel: $missing outputs missing, $temps temp files left by the killed task"

scontrol requeue "${job2}_$victim" || fail "scontrol requeue ${job2}_$victim failed"
deadline=$((SECONDS + 180))
while :; do
  state=$(task_field "${job2}_$victim" JobState)
  case "$state" in
    COMPLETED) break ;;
    FAILED | CANCELLED | TIMEOUT | NODE_FAIL | OUT_OF_MEMORY) fail "the requeued task $victim ended $state" ;;
  esac
  [ $SECONDS -lt $deadline ] || fail "the requeued task $victim did not complete within 180 s (state $state)"
  sleep 0.5
done
[ "$(task_field "${job2}_$victim" ExitCode)" = 0:0 ] || fail "the requeued task exited $(task_field "${job2}_$victim" ExitCode)"
[ "$(task_field "${job2}_$victim" Restarts)" = 1 ] || fail "task $victim was not restarted once"
check_outputs "$out" "after the requeue"
ok2=$(ok_frames "$T"/jobs/run2_*.log)
[ "$(uniq -d <<< "$ok2")" = "" ] || fail "frames computed twice across the cancel and the requeue: $(uniq -d <<< "$ok2" | tr '\n' ' ')"
[ "$(wc -l <<< "$ok2")" = $shot_frames ] || fail "the logs of job $job2 show $(wc -l <<< "$ok2") frames computed, not $shot_frames"
skipped=$(grep -c 'skipped (output up to date' "$T/jobs/run2_$victim.log" || true)
say "   requeued task: completed, skipped the $skipped frames done before the cancel; $shot_frames outputs, each written once, no temp files"

# ---------------------------------------------------------------------------------------
# 4. A finished task run twice: nothing recomputed, outputs untouched
# ---------------------------------------------------------------------------------------
say "4. task 2 run again (sbatch --array=2)"
before=$(cd "$out" && stat -c '%n %Y.%y' shot.*.ssdo.exr | md5sum)
job3=$(sbatch --wait --parsable --array=2 --cpus-per-task=1 --chdir="$T" \
  --output="$T/jobs/run3_%a.log" "$job_script" $chunks "$out" "$pattern" "${options[@]}")
rc=$?
[ $rc = 0 ] || fail "the rerun of task 2 exited $rc"
[ "$(grep -c 'skipped (output up to date' "$T/jobs/run3_2.log")" = $((shot_frames / chunks)) ] ||
  fail "the rerun of task 2 did not skip its $((shot_frames / chunks)) frames"
[ -z "$(ok_frames "$T/jobs/run3_2.log")" ] || fail "the rerun of task 2 recomputed frames"
[ "$(cd "$out" && stat -c '%n %Y.%y' shot.*.ssdo.exr | md5sum)" = "$before" ] || fail "the rerun changed outputs"
check_outputs "$out" "after the rerun"
say "   job ${job3%%;*}: $((shot_frames / chunks)) frames skipped, outputs untouched"

echo
echo "Wall time over $shot_frames frames ($cpus CPUs, --method gtao --preset high; load average $(cut -d' ' -f1-3 /proc/loadavg)):"
echo "  one ssdo process:                 $t_single s"
echo "  array job, $chunks tasks x 1 CPU:     $span1 s from submission to the last task's end (slurmctld log)"
echo "                                    $t_array s until sbatch --wait returned (it polls)"
echo "PASS"
