#!/usr/bin/env bash
# Library code never prints, exits or reads the environment (ARCHITECTURE.md invariants).
#
# Greps every .rs file under crates/ and src/, except the command layer (src/cli/, src/main.rs),
# for printing macros, process exits, environment reads and the standard streams. Skipped:
# files named tests.rs, files under a tests/ directory, comment lines, and the rest of a file
# from its first `#[cfg(test)]` line on (tests may print and read the environment). Allowed:
# the `_exit` of the mapped-file fault handler (crates/volume/src/out_of_core/mapfault.rs:
# libc::_exit, the way a signal handler may end the process).
#
# Prints file:line: text for each violation and exits 1 if there was any.
set -euo pipefail
cd "$(dirname "$0")/.."

# Extended regular expressions (grep -E), one per forbidden use.
patterns=(
    '(^|[^a-z_])e?println!'
    '(^|[^a-z_])e?print!'
    '(^|[^a-z_])dbg!'
    'std::process::exit'
    '(^|[^a-z_:])process::exit'
    'std::env::var'
    'env::var_os'
    'std::env::vars'
    'std::io::stdout'
    'std::io::stderr'
    'temp_dir\(\)'
    'current_dir\(\)'
    'home_dir'
)
regex=$(IFS='|'; echo "${patterns[*]}")
# libc::_exit, allowed in the fault handler only
exit_regex='(^|[^a-z_])_exit\('
mapfault=crates/volume/src/out_of_core/mapfault.rs

status=0
while IFS= read -r -d '' file; do
    case "$file" in
        src/cli/* | src/main.rs) continue ;;
        */tests/* | */tests.rs | tests.rs) continue ;;
    esac
    # Line numbers of violations before the first #[cfg(test)] line.
    re=$regex
    [ "$file" = "$mapfault" ] || re="$regex|$exit_regex"
    hits=$(awk -v re="$re" '
        /^[[:space:]]*#\[cfg\(test\)\]/ { exit }
        $0 ~ re {
            line = $0
            sub(/^[[:space:]]+/, "", line)
            # Comments may name what they avoid.
            if (line ~ /^\/\//) next
            printf "%s:%d: %s\n", FILENAME, FNR, line
        }' "$file")
    if [ -n "$hits" ]; then
        echo "$hits"
        status=1
    fi
done < <(find crates src -name '*.rs' -print0 | sort -z)

if [ "$status" -ne 0 ]; then
    echo "check-quiet.sh: library code above prints, exits or reads the environment;" >&2
    echo "check-quiet.sh: return the data or error to src/cli, log through the log facade, or pass the value in" >&2
fi
exit "$status"
