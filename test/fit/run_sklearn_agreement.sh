#!/bin/sh
# ctest wrapper: run the scikit-learn agreement test with the oracle python, or skip (77).
# usage: run_sklearn_agreement.sh PYTHON GMM_FIT WORK_DIR
PY="$1"; GMM_FIT="$2"; WORK="$3"
if [ ! -x "$PY" ]; then
  echo "SKIP: oracle python $PY not found (install python3-sklearn)"
  exit 77
fi
exec "$PY" "$(dirname "$0")/sklearn_agreement.py" "$GMM_FIT" "$WORK"
