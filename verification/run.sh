#!/usr/bin/env bash
# Independent verification suite of ncform. Run from anywhere:
#   bash verification/run.sh          # the suites verify_*.py (CI)
#   bash verification/run.sh --full   # and the paper-size full_*.py (long)
# 1. creates verification/.venv (python3 -m venv) and installs the pinned
#    requirements.txt into it (again only when requirements.txt changed),
# 2. builds the binary: cargo build --release --bin ncform --tests (repo
#    root; with the tests, so that the dependencies' features are those of
#    `cargo test --release` and the binary that run built is reused),
# 3. runs every verification/verify_*.py suite (and slurm.sh, the sweep's
#    Slurm backend on a one-node Slurm it starts) with --ncform PATH; each
#    prints PASS/FAIL lines and one "CHECK-SUMMARY passed=N failed=M" line,
# 4. ends with exactly one line "verification: N passed, N failed" and exits
#    non-zero if any check failed (the build counts as one check; a suite that
#    crashes without its summary line counts as one failed check).
set -euo pipefail

full=0
if [ "${1:-}" = "--full" ]; then
    full=1
fi

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(cd "$here/.." && pwd)"
venv="$here/.venv"
py="${PYTHON:-python3}"

# --- 1. Python environment ------------------------------------------------
if [ ! -x "$venv/bin/python" ]; then
    echo "# creating $venv"
    "$py" -m venv "$venv"
fi
stamp="$venv/.requirements.installed"
if ! cmp -s "$here/requirements.txt" "$stamp"; then
    echo "# installing verification/requirements.txt"
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check \
        -r "$here/requirements.txt"
    cp "$here/requirements.txt" "$stamp"
fi

passed=0
failed=0

# --- 2. Build -----------------------------------------------------------------
bin="$repo/target/release/ncform"
echo "# cargo build --release --bin ncform --tests"
if (cd "$repo" && cargo build --release --bin ncform --tests); then
    echo "PASS [build] cargo build --release --bin ncform --tests succeeds"
    passed=$((passed + 1))
else
    echo "FAIL [build] cargo build --release --bin ncform --tests succeeds"
    failed=$((failed + 1))
    bin=""   # the suites then fail their checks that need the binary
fi

# --- 3. Suites ----------------------------------------------------------------
shopt -s nullglob
suites=("$here"/verify_*.py)
if [ "$full" -eq 1 ]; then
    suites+=("$here"/full_*.py)
fi
# The Slurm backend of `ncform sweep` on a one-node Slurm started by the
# script itself (docs/studies.md, "Slurm"); a bash script, same protocol.
suites+=("$here/slurm.sh")
for suite in "${suites[@]}"; do
    name="$(basename "$suite")"
    echo "# running $name"
    log="$(mktemp)"
    set +e
    if [[ "$suite" == *.sh ]]; then
        bash "$suite" --ncform "$bin" 2>&1 | tee "$log"
    else
        "$venv/bin/python" "$suite" --ncform "$bin" 2>&1 | tee "$log"
    fi
    rc=${PIPESTATUS[0]}
    set -e
    summary="$(grep -E '^CHECK-SUMMARY passed=[0-9]+ failed=[0-9]+$' "$log" | tail -n 1 || true)"
    rm -f "$log"
    if [ -n "$summary" ]; then
        p="$(sed -E 's/^CHECK-SUMMARY passed=([0-9]+) failed=([0-9]+)$/\1/' <<<"$summary")"
        f="$(sed -E 's/^CHECK-SUMMARY passed=([0-9]+) failed=([0-9]+)$/\2/' <<<"$summary")"
        passed=$((passed + p))
        failed=$((failed + f))
        if [ "$rc" -ne 0 ] && [ "$f" -eq 0 ]; then
            echo "FAIL [$name] exited $rc although it reported no failed check"
            failed=$((failed + 1))
        fi
    else
        echo "FAIL [$name] ended (exit $rc) without its CHECK-SUMMARY line"
        failed=$((failed + 1))
    fi
done

# --- 4. Closing line ------------------------------------------------------------
echo "verification: $passed passed, $failed failed"
[ "$failed" -eq 0 ]
