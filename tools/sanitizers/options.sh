# The sanitizers' run-time options for thicket's tests, sourced by scripts/test:
#   source tools/sanitizers/options.sh address|thread REPORT_DIR
# Every finding stops the process that made it (halt_on_error, and -fno-sanitize-recover=all at
# build time for UBSan), so the test that ran it fails. ASan's and TSan's reports go to
# REPORT_DIR/<tool>.<pid> (log_path), where scripts/test finds those of the programs that tests
# start too; UBSan's go to stderr (in a build with ASan it ignores its own log_path).
# shellcheck shell=bash
sanitizer_dir=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
case $1 in
  address)
    export ASAN_OPTIONS="halt_on_error=1:detect_leaks=1:detect_stack_use_after_return=1:\
check_initialization_order=1:log_path=$2/asan"
    export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1"
    ;;
  thread)
    export TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:log_path=$2/tsan:\
suppressions=$sanitizer_dir/tsan.supp"
    ;;
  *)
    echo "tools/sanitizers/options.sh: address or thread, not '$1'" >&2
    return 2
    ;;
esac
