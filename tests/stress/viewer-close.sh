#!/usr/bin/env bash
# Stress for the viewer's exit during `--save-run` (not a CI test: it takes about an hour).
#
#   bash tests/stress/viewer-close.sh [CLOSES] [BINARY]
#   VIEWER_CLOSE_LOAD=0 bash tests/stress/viewer-close.sh ...   # when other work already loads both cores
#
# Opens the viewer training live with `--save-run` under Xvfb, CLOSES times (default 200), and closes its
# window as a window manager's close button does (tests/close_window.py) after a delay that cycles through
# 0 to 12 s in steps of 0.25 s, so the close lands at every moment of the run: before the first frame,
# during the first save into the kept folder, between an episode's end and its checkpoint, mid-episode.
# Meanwhile two `--train --threads 1` runs keep both cores busy, the load under which the race was seen.
#
# Each close must end the process within 60 s with status 0 and a line saying how many episodes the kept
# folder holds, or status 1 and "not saved" (closed before the first episode ended: no folder). A kept
# folder must hold exactly that many metrics.csv rows and `--resume` must continue it by one episode. A
# viewer still running 60 s after its close has every thread's stack written (gdb) into the log folder,
# is sent a second close (which tells a close that never arrived, "ended", from a viewer that no longer
# answers one, "stuck"), and is killed. Prints one line per close and a closing count; exits non-zero on any failure.
set -uo pipefail
cd "$(dirname "$0")/../.."
closes="${1:-200}"
bin="${2:-target/release/coevo}"
[ -x "$bin" ] || { echo "viewer-close: $bin: no such executable (cargo build --release --features viewer)"; exit 2; }
for tool in xvfb-run gdb /usr/bin/python3; do
    command -v "$tool" >/dev/null || { echo "viewer-close: $tool is missing (apt-get install xvfb gdb python3-xlib)"; exit 2; }
done
work="$(mktemp -d /tmp/viewer-close.XXXXXX)"
echo "viewer-close: $closes closes of $bin; logs in $work"

# The scene: the paper's, with 50-step episodes so several episode boundaries (saves) pass in a few seconds.
cp scenes/paper.ron "$work/short.ron"
sed -i 's/episode_steps: [0-9]*/episode_steps: 50/' "$work/short.ron"
grep -q 'episode_steps: 50' "$work/short.ron" || { echo "viewer-close: could not shorten the scene's episodes"; exit 2; }

# Two cores' load, restarted whenever a training ends, until this script ends.
load() {
    while :; do
        rm -rf "$work/load-$1"
        "$bin" --train --scene scenes/paper.ron --seed "$1" --threads 1 --quiet --out "$work/load-$1" >/dev/null 2>&1
    done
}
if [ "${VIEWER_CLOSE_LOAD:-1}" != 0 ]; then
    load 1 & load1=$!
    load 2 & load2=$!
    trap 'kill $load1 $load2 2>/dev/null; pkill -f "$work/load-" 2>/dev/null' EXIT
fi

ok=0 unsaved=0 failed=0
for i in $(seq 1 "$closes"); do
    delay="$(awk -v i="$i" 'BEGIN { printf "%.2f", ((i - 1) % 49) * 0.25 }')"
    dir="$work/close-$i"
    mkdir -p "$dir"
    # The close, then up to 60 s for the exit; a viewer still alive has its threads' stacks taken and is killed.
    xvfb-run -a -s "-screen 0 1280x720x24" sh -c "
        RUST_LOG=warn,coevo=info,coevo::viewer=debug,bevy_winit=info,bevy_window=info,wgpu=error,naga=error XDG_RUNTIME_DIR=$dir \\
            $bin --scene $work/short.ron --steps-per-frame 25 --save-run $dir/saved > $dir/out.txt 2> $dir/err.txt & pid=\$!
        /usr/bin/python3 tests/close_window.py $delay > $dir/closer.txt 2>&1; echo \$? > $dir/closer-status
        for k in \$(seq 300); do kill -0 \$pid 2>/dev/null || break; sleep 0.2; done
        if kill -0 \$pid 2>/dev/null; then
            gdb -p \$pid -batch -ex 'thread apply all bt' > $dir/stacks.txt 2>&1
            # A second close: a viewer that ends on it was never sent the first; one that does not is stuck.
            /usr/bin/python3 tests/close_window.py 0 > $dir/second-closer.txt 2>&1
            for k in \$(seq 50); do kill -0 \$pid 2>/dev/null || break; sleep 0.2; done
            if kill -0 \$pid 2>/dev/null; then echo stuck > $dir/second-close; else echo ended > $dir/second-close; fi
            kill -9 \$pid 2>/dev/null
        fi
        wait \$pid; echo \$? > $dir/status" >/dev/null 2>&1
    status="$(cat "$dir/status" 2>/dev/null || echo none)"
    line="$(grep -h "holds the live run's" "$dir/out.txt" 2>/dev/null)"
    verdict=""
    if [ -s "$dir/stacks.txt" ]; then
        second="$(cat "$dir/second-close" 2>/dev/null)"
        verdict="FAILED: still running 60 s after the close; a second close: ${second:-not sent} (stacks in $dir/stacks.txt)"
    elif [ "$status" = 0 ] && [ -n "$line" ]; then
        held="$(echo "$line" | sed "s/.*holds the live run's \([0-9]*\) episodes.*/\1/")"
        rows=$(($(wc -l < "$dir/saved/metrics.csv") - 1))
        if [ "$rows" != "$held" ]; then
            verdict="FAILED: the line says $held episodes, metrics.csv holds $rows rows"
        elif ! "$bin" --resume "$dir/saved" --episodes $((held + 1)) --quiet > "$dir/resume.txt" 2>&1; then
            verdict="FAILED: --resume refused the kept folder: $(tail -1 "$dir/resume.txt")"
        else
            verdict="ok: kept $held episodes, resumed"
            ok=$((ok + 1))
        fi
    elif [ "$status" = 1 ] && grep -q "not saved" "$dir/err.txt" && [ ! -e "$dir/saved" ]; then
        verdict="ok: closed before the first save, nothing kept"
        unsaved=$((unsaved + 1))
    elif [ "$(cat "$dir/closer-status" 2>/dev/null)" != 0 ]; then
        verdict="FAILED: the close was never sent: $(tail -1 "$dir/closer.txt")"
    else
        verdict="FAILED: status $status: $(tail -1 "$dir/err.txt" 2>/dev/null)"
    fi
    case "$verdict" in FAILED*) failed=$((failed + 1)) ;; *) rm -rf "$dir" ;; esac
    echo "close $i after ${delay} s: $verdict"
done
echo "viewer-close: $closes closes: $ok kept and resumed, $unsaved closed before the first save, $failed failed"
[ "$failed" = 0 ]
