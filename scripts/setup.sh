#!/usr/bin/env bash
# Sets up a fresh machine for Repertoire: fetches the MuJoCo 3.17.0 C library from the `mujoco`
# wheel on PyPI (the only network access) and unpacks it into third_party/mujoco/lib, which
# .cargo/config.toml points mujoco-rs at. Re-running it is a no-op once the library is in place.
set -euo pipefail

MUJOCO_VERSION=3.17.0
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
lib_dir="$root/third_party/mujoco/lib"
lib="$lib_dir/libmujoco.so.$MUJOCO_VERSION"

if [ -f "$lib" ] && [ -L "$lib_dir/libmujoco.so" ]; then
  exit 0
fi

command -v cargo >/dev/null || { echo "setup: cargo is not installed (https://rustup.rs)" >&2; exit 1; }
py="$(command -v python3 || command -v python || true)"
[ -n "$py" ] || { echo "setup: python3 with pip is needed to fetch the MuJoCo wheel" >&2; exit 1; }
"$py" -m pip --version >/dev/null 2>&1 || { echo "setup: pip is missing for $py" >&2; exit 1; }

tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
echo "setup: fetching MuJoCo $MUJOCO_VERSION from PyPI (wheel 'mujoco==$MUJOCO_VERSION')" >&2
# The shared library inside is the same for every CPython tag, so any wheel for this platform serves.
"$py" -m pip download --quiet --no-deps --only-binary=:all: --dest "$tmp" "mujoco==$MUJOCO_VERSION"
wheel="$(ls "$tmp"/mujoco-"$MUJOCO_VERSION"-*.whl | head -n 1)"
"$py" - "$wheel" "$tmp/out" "$MUJOCO_VERSION" <<'PY'
import sys, zipfile, pathlib
wheel, out, version = sys.argv[1], pathlib.Path(sys.argv[2]), sys.argv[3]
name = f"mujoco/libmujoco.so.{version}"
with zipfile.ZipFile(wheel) as z:
    if name not in z.namelist():
        sys.exit(f"setup: {wheel} has no {name}")
    out.mkdir(parents=True, exist_ok=True)
    (out / f"libmujoco.so.{version}").write_bytes(z.read(name))
PY

mkdir -p "$lib_dir"
# Move into place last, so an interrupted run never leaves a half-written library behind.
mv "$tmp/out/libmujoco.so.$MUJOCO_VERSION" "$lib.partial"
mv "$lib.partial" "$lib"
ln -sfn "libmujoco.so.$MUJOCO_VERSION" "$lib_dir/libmujoco.so"
echo "setup: MuJoCo $MUJOCO_VERSION installed in third_party/mujoco/lib" >&2
