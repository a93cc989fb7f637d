# Shared by the command-line test scripts (source it after setting nothing):
# ok / bad count passes and failures; expect CODE PATTERN -- command... runs the command
# and checks its exit status, that PATTERN (grep -E) is in its stdout+stderr, and that it
# neither crashed nor leaked an HDF5 error stack.
fails=0 passes=0
ok() { passes=$((passes + 1)); }
bad() { echo "FAIL: $*"; fails=$((fails + 1)); }
expect() {
  local code=$1 pattern=$2; shift 3
  local out rc
  out=$("$@" 2>&1); rc=$?
  if [ "$rc" != "$code" ]; then bad "'$*' exited $rc, expected $code; output:"; echo "$out" | head -20; return; fi
  if ! grep -qE -- "$pattern" <<<"$out"; then bad "'$*' output lacks /$pattern/:"; echo "$out" | head -20; return; fi
  if grep -qE 'terminate called|Segmentation|Aborted|core dumped|stack trace|HDF5-DIAG' <<<"$out"; then bad "'$*' crashed or leaked HDF5 errors: $out"; return; fi
  ok
}
