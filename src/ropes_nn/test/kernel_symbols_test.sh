#!/usr/bin/env bash
# The GEMM kernel objects of each instruction-set level (src/gemm_kernel.hpp) must define
# nothing the linker could take for another level's copy: no global or weak symbol outside
# the level's own namespaces (ropes_eigen_<level>, ropes::nn::kernel_<level>), and no static
# constructor (code of that level run at start-up on any CPU).
# Usage: kernel_symbols_test.sh LEVEL=OBJECT...
set -euo pipefail
failed=0
for pair in "$@"; do
  level=${pair%%=*}
  object=${pair#*=}
  [ -f "$object" ] || { echo "FAIL: $object: no such object" >&2; exit 1; }
  # defined symbols that are global (upper-case type) or weak/unique (V, W, u)
  leaked=$(nm -C --defined-only "$object" | awk '$2 ~ /^[A-Z]$/ || $2 == "u"' \
    | grep -v -e "ropes_eigen_${level}::" -e "ropes::nn::kernel_${level}::" \
              -e ' DW\.ref\.__gxx_personality_v0$' || true)
  if [ -n "$leaked" ]; then
    echo "FAIL: the $level kernel object defines symbols outside its namespaces:" >&2
    echo "$leaked" | head -20 >&2
    failed=1
  fi
  if objdump -h "$object" | grep -qE '\.(init_array|ctors)'; then
    echo "FAIL: the $level kernel object has a static constructor" >&2
    failed=1
  fi
  ours=$(nm -C --defined-only "$object" | grep -c "ropes::nn::kernel_${level}::kGemm" || true)
  [ "$ours" = 1 ] || { echo "FAIL: $level: no ropes::nn::kernel_${level}::kGemm" >&2; failed=1; }
  echo "$level: $(nm --defined-only "$object" | wc -l) symbols, none outside its namespaces"
done
exit "$failed"
