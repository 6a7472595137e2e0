#!/usr/bin/env bash
# Every C++ file of the workspace is formatted by the committed .clang-format.
# Usage: format_test.sh WORKSPACE
set -euo pipefail
cd "$1"
command -v clang-format >/dev/null || { echo "clang-format is not installed (ci/install-deps installs it)" >&2; exit 1; }
mapfile -t files < <(git ls-files -co --exclude-standard -- 'src/*.cpp' 'src/*.hpp' 'tests/*.cpp' 'tests/*.hpp' 2>/dev/null \
                     || find src tests -name '*.cpp' -o -name '*.hpp')
[ "${#files[@]}" -gt 0 ] || { echo "no C++ files found under src/ and tests/" >&2; exit 1; }
if clang-format --dry-run --Werror --style=file "${files[@]}"; then
  echo "format: ${#files[@]} files formatted as .clang-format says"
else
  echo "format: run 'clang-format -i --style=file' on the files above" >&2
  exit 1
fi
