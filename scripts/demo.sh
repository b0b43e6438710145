#!/usr/bin/env bash
# README command 1: set up, then run the main job on built-in data (no download needed).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/scanalign demo --out out/demo
.venv/bin/scanalign pick --demo --out out/pick
