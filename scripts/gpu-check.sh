#!/usr/bin/env bash
# scripts/gpu-check.sh: the evaluator and the staged fit measured on a machine
# with a real GPU, as markdown for docs/PERFORMANCE.md (issue 31).
#
# It needs nothing but the built binary, a Vulkan loader and driver, and the
# repository's data/ (no Rust toolchain, no network, no python or jq). It
# measures, on data/stair_4.5kg.csv (4000 samples):
#   - evaluator throughput (`mckibben bench --backend gpu --time-reference`)
#     at N = 1e5, 1e6, 4e6 for the classic model, the generalized model and
#     the classic model with effect stages (creep, delay, saturation), and the
#     CPU path on the same populations (the speed-up is CPU median / GPU
#     median), end to end and, from the device's timestamps, the kernels
#     alone, with each model kernel's share of the device's f32 ceiling;
#   - the device's f32 ceiling: the calibration kernel, timed by the device's
#     clock in each bench call (dependent mul-adds, independent chains, pow);
#   - CPU/GPU agreement on each population: the largest relative SSE
#     difference and whether the best 100 candidates rank alike;
#   - a staged fit (`mckibben fit`, classic) at N = 1e5 and 1e6 on both
#     backends: wall time, final SSE, validation fit %, whether the two
#     backends end on the same parameters, and from the global stage of its
#     JSON the host's time a row (outside the evaluator) and the device's
#     time a generation (the kernels' timestamps), the polish's seconds and
#     the process's peak resident memory;
#   - the population sweep (`mckibben sweep`, classic cases #1000–#1004 at
#     N = 1e3 and 1e4 on both backends): what a larger population buys in
#     passing fits and what it costs in wall time;
#   - the default `mckibben diagnose` on both backends: wall time, verdict,
#     and whether the two JSON documents are byte-identical.
# It prints the tables on stdout and writes them to --out as each section
# ends, so that a run stopped from outside leaves what it measured; with
# --deadline it starts no section past that many seconds and says which it
# skipped (docs/PERFORMANCE.md).
#
#   cargo build --release && scripts/gpu-check.sh
#   scripts/gpu-check.sh --bin ./mckibben --out gpu-check.md --deadline 420
#   scripts/gpu-check.sh --small          # CI smoke size, runs on lavapipe
#                                         # (the sweep: case #1000 at N = 100)
set -euo pipefail

usage() {
    cat <<'EOF'
usage: scripts/gpu-check.sh [--bin PATH] [--small] [--out FILE] [--deadline S] [--gens G] [--data FILE]

  --bin PATH   the mckibben binary (default: $MCKIBBEN, else target/release/mckibben)
  --small      the CI smoke size: bench at N = 1000, 4000; fits at N = 200, 10 generations;
               the sweep on one case at N = 100
  --out FILE   also write the markdown to FILE, section by section as each ends
  --deadline S start no section (a model's bench, a fit's population, a sweep, the
               diagnosis) once S seconds have passed; the tables name what was skipped
  --gens G     generations of each staged fit's global stage (default: 30; --small: 10)
  --data FILE  experiment CSV (default: data/stair_4.5kg.csv of this repository)

  GNU_TIME=PATH  GNU time, for the staged fits' peak memory (default: /usr/bin/time;
                 without it that column shows —)
EOF
}

die() {
    echo "gpu-check: $*" >&2
    exit 2
}

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bin="${MCKIBBEN:-$root/target/release/mckibben}"
gnu_time="${GNU_TIME:-/usr/bin/time}"
data="$root/data/stair_4.5kg.csv"
small=0
out=""
deadline=""
gens=""
while [ $# -gt 0 ]; do
    case "$1" in
        --bin)
            [ $# -ge 2 ] || die "--bin needs a path"
            bin="$2"
            shift 2
            ;;
        --out)
            [ $# -ge 2 ] || die "--out needs a file name"
            out="$2"
            shift 2
            ;;
        --data)
            [ $# -ge 2 ] || die "--data needs a file name"
            data="$2"
            shift 2
            ;;
        --deadline)
            [ $# -ge 2 ] || die "--deadline needs a number of seconds"
            [[ "$2" =~ ^[0-9]+$ ]] || die "--deadline: expected a whole number of seconds, got '$2'"
            deadline="$2"
            shift 2
            ;;
        --gens)
            [ $# -ge 2 ] || die "--gens needs a number"
            [[ "$2" =~ ^[1-9][0-9]*$ ]] || die "--gens: expected a positive whole number, got '$2'"
            gens="$2"
            shift 2
            ;;
        --small)
            small=1
            shift
            ;;
        -h | --help)
            usage
            exit 0
            ;;
        *)
            usage >&2
            die "unknown argument '$1'"
            ;;
    esac
done
[ -x "$bin" ] || die "--bin: '$bin' is not an executable file (build it with cargo build --release, or pass --bin PATH / MCKIBBEN=PATH)"
[ -f "$data" ] || die "--data: '$data' does not exist"
if [ -n "$out" ]; then
    : >"$out" 2>/dev/null || die "--out: cannot write '$out'"
fi

if [ "$small" = 1 ]; then
    pops="1000,4000"
    repeats=2
    fit_pops=(200)
    sweep_args=(--pop 100 --cases 1000)
    gens="${gens:-10}"
    # A lavapipe smoke run: no time limit needed.
    budget_args=()
else
    pops="100000,1000000,4000000"
    repeats=3
    fit_pops=(100000 1000000)
    sweep_args=(--pop 1000,10000 --cases 1000,1001,1002,1003,1004)
    gens="${gens:-30}"
    # Keeps a slow machine within the 8 minutes; a stop by it is reported.
    budget_args=(--time-budget 60)
fi
effects="creep,delay,saturation"

work="$(mktemp -d "${TMPDIR:-/tmp}/gpu-check.XXXXXX")"
trap 'rm -rf "$work"' EXIT
started=$(date +%s)

# Copies the tables so far to --out (through a temporary beside it, so that a
# run stopped from outside leaves the last whole copy).
publish() {
    if [ -n "$out" ]; then
        cp "$md" "$out.partial" && mv "$out.partial" "$out" || die "--out: cannot write '$out'"
    fi
}

# Whether a section may start: false once --deadline seconds have passed, and
# then the section's name joins the list of those skipped.
skipped=()
in_time() {
    if [ -n "$deadline" ] && [ $(($(date +%s) - started)) -ge "$deadline" ]; then
        skipped+=("$1")
        echo "gpu-check: skipped (--deadline $deadline s): $1" >&2
        return 1
    fi
}

# Runs the binary with a log; on failure names the step and shows the log.
run() {
    local step="$1"
    shift
    echo "gpu-check: $step" >&2
    if ! "$bin" "$@" >"$work/stdout" 2>"$work/stderr"; then
        echo "gpu-check: FAILED: $step: $bin $*" >&2
        tail -n 20 "$work/stderr" >&2
        exit 1
    fi
}

# As run, and writes the step's peak resident memory in MB to $work/peak_mb:
# GNU time's maximum resident set size, or — where $GNU_TIME (default
# /usr/bin/time) is not GNU time (the kernel forgets a process's high-water
# mark when it exits).
run_measured() {
    local step="$1"
    shift
    if ! "$gnu_time" -f %M -o "$work/maxrss" true 2>/dev/null; then
        run "$step" "$@"
        echo "—" >"$work/peak_mb"
        return
    fi
    echo "gpu-check: $step" >&2
    if ! "$gnu_time" -f %M -o "$work/maxrss" "$bin" "$@" >"$work/stdout" 2>"$work/stderr"; then
        echo "gpu-check: FAILED: $step: $bin $*" >&2
        tail -n 20 "$work/stderr" >&2
        exit 1
    fi
    awk '{ printf "%.0f\n", $1 / 1024 }' "$work/maxrss" >"$work/peak_mb"
}

# A top-level key of the binary's pretty-printed JSON (two-space indent),
# e.g. json_top file seconds.
json_top() {
    sed -n "s/^  \"$2\": \"\{0,1\}\([^\",]*\)\"\{0,1\},\{0,1\}\$/\1/p" "$1" | head -n 1
}

# --- the machine ----------------------------------------------------------
run "adapter" bench --synthetic 100 --pop 1 --repeats 1 --backend gpu --json
adapter=$(sed -n 's/^ *"adapter": "\(.*\)",$/\1/p' "$work/stdout" | head -n 1)
gpu="—"
if command -v nvidia-smi >/dev/null 2>&1; then
    gpu=$(nvidia-smi --query-gpu=name,driver_version --format=csv,noheader 2>/dev/null | head -n 1 || true)
    gpu="${gpu:-—}"
fi
cpu=$(sed -n 's/^model name[[:space:]]*: //p' /proc/cpuinfo 2>/dev/null | head -n 1)
cpu="${cpu:-unknown}"
cores=$(nproc)
version=$("$bin" --version)
when=$(date -u '+%Y-%m-%d %H:%M UTC')
samples=$(($(grep -cv '^#' "$data") - 1))

md="$work/table.md"
{
    echo "### \`scripts/gpu-check.sh$([ "$small" = 1 ] && echo " --small")\`, $when"
    echo
    echo "- binary: $version"
    echo "- adapter (wgpu): $adapter"
    echo "- nvidia-smi: $gpu"
    echo "- CPU: $cpu, $cores logical cores"
    echo "- data: $(basename "$data") ($samples samples); populations drawn with seed 1"
    echo
    echo "Evaluator (\`mckibben bench --backend gpu --time-reference --repeats $repeats --markdown\`;"
    echo "the cpu rows are the batched CPU path on the same populations, the speed-up is CPU median / GPU median;"
    echo "\"median s (range)\" is a whole evaluate call as a fit makes it (the median of the timed calls, their range beside it), \"kernel\" the compute pass alone from the device's timestamps;"
    echo "\"share of ceiling\" is the kernels' f32 operations a second over the calibration's independent-chain rate below):"
    echo
} >"$md"

# --- evaluator throughput and agreement -----------------------------------
# Each bench call prints its rows, a blank line and its calibration's rows.
calibration="$work/calibration.md"
first=1
for model in classic generalized "classic+effects"; do
    in_time "bench $model" || continue
    args=(bench "$data" --backend gpu --time-reference --repeats "$repeats" --pop "$pops" --markdown)
    case "$model" in
        classic+effects) args+=(--model classic --effects "$effects") ;;
        *) args+=(--model "$model") ;;
    esac
    run "bench $model at N = $pops" "${args[@]}"
    awk 'NF == 0 { exit } { print }' "$work/stdout" >"$work/rows"
    awk 'seen { print } NF == 0 { seen = 1 }' "$work/stdout" >"$work/ceiling"
    if [ "$first" = 1 ]; then
        cat "$work/rows" >>"$md"
        cat "$work/ceiling" >"$calibration"
        first=0
    else
        tail -n +3 "$work/rows" >>"$md"
        tail -n +3 "$work/ceiling" >>"$calibration"
    fi
    publish
done
{
    echo
    echo "Device ceiling (the calibration kernel of each bench call above, \`shaders/calibration.wgsl\`, timed by the device's clock;"
    echo "a mul-add counts two f32 operations, a pow one; the independent chains' rate is the ceiling):"
    echo
    if [ -s "$calibration" ]; then
        cat "$calibration"
    else
        echo "— (the adapter offers no timestamp queries)"
    fi
} >>"$md"
publish

# --- staged fits on both backends ------------------------------------------
{
    echo
    echo "Staged fit (\`mckibben fit --model classic --pop N --gens $gens --backend B${budget_args[*]:+ ${budget_args[*]}}\`,"
    echo "seed 1; wall time includes start-up and the figures written to --out):"
    echo
    echo "host µs/row and device ms/gen: the global stage of the fit's JSON, (seconds − evaluator_seconds) / evaluations"
    echo "and kernel_seconds / steps (the kernels on the device's clock; — on the CPU); gen / max: the stage's seconds a"
    echo "generation over the larger of the host's (seconds − evaluator_seconds) and the device's a generation"
    echo "(1 where they overlap fully, 2 where they take turns at equal shares; — on the CPU); polish s: the seconds of the"
    echo "fit's polish stages, every try's Levenberg–Marquardt starts (on the GPU their residuals are read back each round);"
    echo "peak host MB: the process's maximum resident set size (GNU time; — without it):"
    echo
    echo "| N | gens (all stages) | backend | wall s | fit s | stop | final SSE | val fit % | GPU/CPU speed-up | same parameters as CPU | host µs/row | device ms/gen | gen / max | polish s | peak host MB |"
    echo "|---:|---:|---|---:|---:|---|---:|---:|---:|---|---:|---:|---:|---:|---:|"
} >>"$md"

# The global stage's "steps evaluations seconds evaluator_seconds kernel_seconds"
# from a fit's JSON (the stage's members are indented six spaces).
global_stage() {
    awk '/^      "stage": "global"/ { inside = 1 }
        inside && /^    }/ { exit }
        inside { gsub(/[",]/, ""); v[$1] = $2 }
        END { print v["steps:"], v["evaluations:"], v["seconds:"], v["evaluator_seconds:"], v["kernel_seconds:"] }' "$1"
}

# The seconds of a fit's polish stages, summed (the stages' members are
# indented six spaces).
polish_seconds() {
    awk '/^      "stage": / { polish = ($2 == "\"polish\",") }
        polish && /^      "seconds": / { gsub(/,/, "", $2); sum += $2; polish = 0 }
        END { printf "%.2f\n", sum }' "$1"
}

# The "params" object of a fit's JSON, one "name": value per line.
params() {
    awk '/^  "params": \{/ { inside = 1; next } inside && /^  \}/ { exit } inside { gsub(/[ ,]/, ""); print }' "$1"
}

for n in "${fit_pops[@]}"; do
    in_time "fits at N = $n" || continue
    for backend in cpu gpu; do
        t0=$(date +%s.%N)
        run_measured "fit at N = $n on $backend" fit "$data" --model classic --pop "$n" --gens "$gens" \
            --backend "$backend" --seed 1 "${budget_args[@]}" --json --out "$work/fit-$backend-$n"
        t1=$(date +%s.%N)
        cp "$work/stdout" "$work/fit-$backend-$n.json"
        cp "$work/peak_mb" "$work/peak-$backend-$n"
        awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.2f\n", b - a }' >"$work/wall-$backend-$n"
    done
    cpu_json="$work/fit-cpu-$n.json"
    gpu_json="$work/fit-gpu-$n.json"
    cpu_wall=$(cat "$work/wall-cpu-$n")
    gpu_wall=$(cat "$work/wall-gpu-$n")
    if [ "$(params "$cpu_json")" = "$(params "$gpu_json")" ]; then
        same="yes (bit-identical)"
    else
        # The largest relative difference of a parameter, |g − c| / max(|c|, 1e-12).
        same=$(paste -d' ' <(params "$cpu_json" | tr ':' ' ') <(params "$gpu_json" | tr ':' ' ') |
            awk '{ d = $4 - $2; if (d < 0) d = -d; c = $2 < 0 ? -$2 : $2; if (c < 1e-12) c = 1e-12;
                   if (d / c > m) { m = d / c; w = $1 } }
                 END { printf "no: max rel param diff %.2e (%s)\n", m, w }')
    fi
    for backend in cpu gpu; do
        f="$work/fit-$backend-$n.json"
        wall=$(cat "$work/wall-$backend-$n")
        if [ "$backend" = gpu ]; then
            speedup=$(awk -v c="$cpu_wall" -v g="$gpu_wall" 'BEGIN { printf "%.2f×\n", c / g }')
            alike="$same"
        else
            speedup="1×"
            alike="reference"
        fi
        # Host µs a row and device ms a generation of the global stage.
        timing=$(global_stage "$f" | awk '{
            host = $2 > 0 ? sprintf("%.3f", ($3 - $4) / $2 * 1e6) : "—"
            on_device = $5 != "" && $5 != "null" && $1 > 0
            device = on_device ? sprintf("%.3f", $5 / $1 * 1e3) : "—"
            larger = ($3 - $4) > $5 ? ($3 - $4) : $5
            ratio = on_device && larger > 0 ? sprintf("%.2f", $3 / larger) : "—"
            printf "%s | %s | %s\n", host, device, ratio }')
        printf '| %s | %s | %s | %s | %.2f | %s | %.6g | %.2f | %s | %s | %s | %s | %s |\n' \
            "$n" "$(json_top "$f" generations)" "$backend" "$wall" "$(json_top "$f" seconds)" \
            "$(json_top "$f" stop)" "$(json_top "$f" sse)" "$(json_top "$f" val_fit_percent)" \
            "$speedup" "$alike" "$timing" "$(polish_seconds "$f")" "$(cat "$work/peak-$backend-$n")" >>"$md"
    done
    publish
done

# --- the population sweep on both backends ---------------------------------
{
    echo
    echo "Population sweep (\`mckibben sweep --family classic ${sweep_args[*]} --backend B --markdown\`, seed 1;"
    echo "generated cases with a known truth, \`fit\`'s defaults; p is the share of single tries that pass alone):"
    echo
} >>"$md"
for backend in cpu gpu; do
    in_time "sweep on $backend" || continue
    run "sweep on $backend" sweep --family classic "${sweep_args[@]}" --backend "$backend" --markdown
    if [ "$backend" = cpu ]; then
        cat "$work/stdout" >>"$md"
    else
        tail -n +3 "$work/stdout" >>"$md"
    fi
    publish
done

# --- the default diagnosis on both backends --------------------------------
if [ "$small" = 1 ]; then
    # lavapipe takes minutes over the default diagnosis: one effect, briefly.
    diagnose_args=(--effects delay --seeds 2 --generations 5 --scratch-seeds 0)
else
    diagnose_args=()
fi
{
    echo
    echo "Diagnosis (\`mckibben diagnose DATA${diagnose_args[*]:+ ${diagnose_args[*]}} --backend B --json\`):"
    echo
    echo "| backend | wall s | verdict | the CPU's JSON |"
    echo "|---|---:|---|---|"
} >>"$md"
for backend in cpu gpu; do
    in_time "diagnose on $backend" || continue
    t0=$(date +%s.%N)
    run "diagnose on $backend" diagnose "$data" "${diagnose_args[@]}" --backend "$backend" --json
    t1=$(date +%s.%N)
    cp "$work/stdout" "$work/diagnose-$backend.json"
    # The names in the top-level "verdict" array (empty: "[]" on one line).
    verdict=$(awk '/^  "verdict": \[\]/ { exit }
        /^  "verdict": \[/ { inside = 1; next }
        inside && /^  \]/ { exit }
        inside { gsub(/^ *"|",?$/, ""); printf "%s%s", sep, $0; sep = ", " }' "$work/diagnose-$backend.json")
    if [ "$backend" = cpu ]; then
        alike="reference"
    elif cmp -s "$work/diagnose-cpu.json" "$work/diagnose-gpu.json"; then
        alike="yes (byte-identical)"
    else
        alike="no"
    fi
    awk -v a="$t0" -v b="$t1" -v be="$backend" -v v="${verdict:-none}" -v s="$alike" \
        'BEGIN { printf "| %s | %.1f | %s | %s |\n", be, b - a, v, s }' >>"$md"
    publish
done

{
    echo
    if [ ${#skipped[@]} -gt 0 ]; then
        echo "Skipped, the --deadline of $deadline s having passed: $(printf '%s; ' "${skipped[@]}" | sed 's/; $//')."
        echo
    fi
    echo "Whole script: $(($(date +%s) - started)) s."
} >>"$md"

cat "$md"
publish
