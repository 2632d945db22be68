#!/usr/bin/env bash
# Regenerates robots/*.toml from URDFs that PyPI packages ship
# (pip install -r requirements-dev.txt: example-robot-data, pybullet):
#
#     bash scripts/import-robots.sh [TREEMANIP_BINARY]
#
# Each robots/config/NAME.toml names its URDF with @EXAMPLE_ROBOT_DATA@ or
# @PYBULLET_DATA@; this fills them in and runs `treemanip robot import`.
set -euo pipefail
cd "$(dirname "$0")/.."
T=${1:-target/release/treemanip}
[ -x "$T" ] || cargo build --release --bin treemanip
ERD=$(python3 -c "import sysconfig, os; print(os.path.join(sysconfig.get_paths()['purelib'], 'cmeel.prefix', 'share', 'example-robot-data', 'robots'))")
PBD=$(python3 -c "import pybullet_data; print(pybullet_data.getDataPath())")
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for config in robots/config/*.toml; do
  name=$(basename "$config" .toml)
  sed -e "s|@EXAMPLE_ROBOT_DATA@|$ERD|g" -e "s|@PYBULLET_DATA@|$PBD|g" "$config" > "$tmp/$name.toml"
  "$T" robot import "$tmp/$name.toml" --out "robots/$name.toml"
  # The temporary path in the recorded command is replaced by the config's.
  sed -i -e "s|$tmp/$name.toml|$config|g" -e "s|$ERD|@EXAMPLE_ROBOT_DATA@|g" -e "s|$PBD|@PYBULLET_DATA@|g" "robots/$name.toml"
done
