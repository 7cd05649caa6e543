#!/usr/bin/env bash
# The game library's exported surface: every dynamic symbol libweft.so defines is a weft_
# function declared in a public header (include/weft.h, include/weft/*.h), none is a lab or
# internal (weft__) name, and the library needs no symbol of the lab (libweft_lab) or the
# asset loaders (libweft_assets). Prints the count that docs/ARCHITECTURE.md reports.
# usage: check_symbols.sh LIBWEFT_SO INCLUDE_DIR
set -euo pipefail
so="$1"
inc="$2"
fail=0
mapfile -t defined < <(nm -D --defined-only "$so" | awk '{print $3}' | sort -u)
if [ "${#defined[@]}" -eq 0 ]; then
    echo "no dynamic symbols read from $so" >&2
    exit 1
fi
headers=("$inc/weft.h" "$inc"/weft/*.h)
for sym in "${defined[@]}"; do
    case "$sym" in
        weft__*) echo "internal symbol exported: $sym" >&2; fail=1; continue ;;
        weft_*) ;;
        *) echo "symbol outside the weft_ namespace exported: $sym" >&2; fail=1; continue ;;
    esac
    if ! grep -qE "\\b$sym\\s*\\(" "${headers[@]}"; then
        echo "exported but declared in no public header: $sym" >&2
        fail=1
    fi
done
# Undefined symbols it needs: only libc/libm/pthread/cJSON-level names, never weft_ ones.
mapfile -t needed < <(nm -D --undefined-only "$so" | awk '{print $2}' | grep -E '^weft' || true)
if [ "${#needed[@]}" -gt 0 ]; then
    echo "libweft needs symbols it does not define (lab or assets?): ${needed[*]}" >&2
    fail=1
fi
echo "libweft exports ${#defined[@]} functions"
exit $fail
