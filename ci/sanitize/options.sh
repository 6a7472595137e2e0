# Sourced by ci/test --sanitize and ci/fuzz: the sanitizer runtime options both use, so the
# tests and the fuzzers check the same things. A leak is a failure; LSan's suppressions
# (lsan.supp) each say why they are not ours; every UBSan report stops the process.
export ASAN_OPTIONS="detect_leaks=1:check_initialization_order=1:strict_init_order=1"
export LSAN_OPTIONS="suppressions=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)/lsan.supp:print_suppressions=0"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
