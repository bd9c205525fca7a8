#!/usr/bin/env bash
# The C++ and CUDA sources follow the repository's .clang-format (clang-format 14, Debian 12's):
# names every tracked file that does not, shows the first one's diff and exits 1; exit 77
# (skipped, with the reason) without clang-format or outside a git checkout.
#   scripts/check_format.sh          # check
#   scripts/check_format.sh --fix    # reformat those files in place
set -uo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
CF="${CLANG_FORMAT:-$(command -v clang-format-14 || command -v clang-format || true)}"
if [ -z "$CF" ]; then echo "clang-format is not installed: the format check is skipped"; exit 77; fi
if ! files=$(git ls-files '*.cpp' '*.h' '*.cu' '*.cuh' 2>/dev/null) || [ -z "$files" ]; then
  echo "not a git checkout: the format check is skipped"; exit 77
fi
bad=()
for f in $files; do
  "$CF" --dry-run --Werror "$f" > /dev/null 2>&1 || bad+=("$f")
done
if [ "${1:-}" = --fix ]; then
  [ ${#bad[@]} -eq 0 ] || "$CF" -i "${bad[@]}"
  echo "reformatted ${#bad[@]} file(s)"; exit 0
fi
if [ ${#bad[@]} -gt 0 ]; then
  printf 'not formatted (%s): %s\n' "$("$CF" --version | head -1)" "${bad[@]}"
  "$CF" "${bad[0]}" | diff -u "${bad[0]}" - | head -40
  echo "fix with: scripts/check_format.sh --fix"
  exit 1
fi
echo "$(wc -w <<< "$files") C++/CUDA files follow .clang-format"
