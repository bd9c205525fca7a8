# Sourced by the shell tests in this folder: a scratch folder $work, removed on exit, and
# `fail MESSAGE`, which prints a failure line and sets failed=1 (the test exits with $failed).
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
failed=0
fail() {
  echo "[ FAILED  ] $*"
  failed=1
}
