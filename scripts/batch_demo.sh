#!/usr/bin/env bash
# Batch runs: set up (with the Ray extra), then the 50-job manifest of synthetic reconstructions
# and pose estimations on the local process pool and on a local Ray instance (docs/batch.md).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/python -m pip install -q "ray>=2.9" "pyarrow>=12"
.venv/bin/scanalign batch examples/batch/mixed50.yaml --executor local --out out/batch-local "$@"
.venv/bin/scanalign batch examples/batch/mixed50.yaml --executor ray --out out/batch-ray "$@"
