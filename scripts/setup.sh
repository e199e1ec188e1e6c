#!/usr/bin/env bash
# Sets up a fresh machine for Repertoire, from package registries only (PyPI, npm, Debian):
#  1. the MuJoCo 3.17.0 C library from the `mujoco` wheel, into third_party/mujoco/lib, which
#     .cargo/config.toml points mujoco-rs at;
#  2. the clip pack, into third_party/clips: the DeepMimic-format walk and turn cycles shipped in
#     the `pybullet` 3.2.7 wheel (pybullet_data/data/motions) and the sit-down/stand-up BVH in the
#     `bvhtoolbox` 0.1.3 sdist (tests/example_files), each checked against its SHA-256.
#  2b. third-party bodies the tests load as users bring them, into third_party/bodies: Gymnasium's
#     MuJoCo humanoid (envs/mujoco/assets/humanoid.xml in the `gymnasium` 1.4.0 wheel) and
#     dm_control's CMU humanoid (locomotion/walkers/assets/humanoid_CMU_V2020.xml in the
#     `dm-control` 1.0.52 wheel), each checked against its SHA-256 (their body maps are
#     committed in bodies/);
#  3. the replay page's npm packages (three.js, inlined into every replay page; playwright-core,
#     which drives the browser test), by `npm ci` in crates/scenes/web from its committed lock file;
#  4. Debian's `chromium` for that test (apt-get, as root or through sudo), if /usr/bin/chromium is
#     missing, Debian's `slurm-wlm` and `munge` (a real one-node Slurm for the --slurm test), if
#     sbatch is missing, and Debian's DejaVu fonts (`fonts-dejavu-core`) for chart text, if no
#     font the report crate looks for is present.
# Re-running it is a no-op once everything is in place.
set -euo pipefail

MUJOCO_VERSION=3.17.0
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
lib_dir="$root/third_party/mujoco/lib"
lib="$lib_dir/libmujoco.so.$MUJOCO_VERSION"

clips_dir="$root/third_party/clips"
bodies_dir="$root/third_party/bodies"
# The last body added: a folder filled before it came is filled again.
bodies_ready() { [ -f "$bodies_dir/.complete" ] && [ -f "$bodies_dir/dm_control/humanoid_CMU_V2020.xml" ]; }
web_dir="$root/crates/scenes/web"

# Steps 3 and 4. Without npm or a way to install chromium this says what to do and goes on: only
# the replay pages and their browser test need them.
web_and_browser() {
  local stamp="$web_dir/node_modules/.setup-lock"
  if ! cmp -s "$web_dir/package-lock.json" "$stamp" 2>/dev/null; then
    if command -v npm >/dev/null; then
      echo "setup: installing the replay page's npm packages in crates/scenes/web (npm ci)" >&2
      (cd "$web_dir" && npm ci --no-audit --no-fund --loglevel=error >&2)
      cp "$web_dir/package-lock.json" "$stamp"
    else
      echo "setup: npm is missing (install Node.js 18+ and npm), so replay pages and their browser test cannot work" >&2
    fi
  fi
  if [ ! -x "${CHROMIUM:-/usr/bin/chromium}" ]; then
    local sudo=""
    [ "$(id -u)" = 0 ] || { command -v sudo >/dev/null && sudo -n true 2>/dev/null && sudo="sudo"; } || true
    if command -v apt-get >/dev/null && { [ "$(id -u)" = 0 ] || [ -n "$sudo" ]; }; then
      echo "setup: installing Debian's chromium for the replay browser test (apt-get install chromium)" >&2
      $sudo apt-get update -qq >&2
      DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq chromium >&2
    else
      echo "setup: ${CHROMIUM:-/usr/bin/chromium} is missing and cannot be installed here (needs apt-get as root or sudo);" \
        "install chromium, or set CHROMIUM to a Chromium binary, for the replay browser test" >&2
    fi
  fi
  # Slurm for `recipe run --slurm` / `ablate --slurm` and their test (tests/slurm.rs starts a
  # one-node cluster with scripts/slurm-local.sh).
  if ! command -v sbatch >/dev/null || ! { command -v slurmctld >/dev/null || [ -x /usr/sbin/slurmctld ]; } \
    || ! { command -v munged >/dev/null || [ -x /usr/sbin/munged ]; }; then
    local sudo=""
    [ "$(id -u)" = 0 ] || { command -v sudo >/dev/null && sudo -n true 2>/dev/null && sudo="sudo"; } || true
    if command -v apt-get >/dev/null && { [ "$(id -u)" = 0 ] || [ -n "$sudo" ]; }; then
      echo "setup: installing Debian's slurm-wlm and munge for the Slurm test (apt-get install slurm-wlm munge)" >&2
      $sudo apt-get update -qq >&2
      DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq slurm-wlm munge >&2
    else
      echo "setup: Slurm is missing and cannot be installed here (needs apt-get as root or sudo);" \
        "install slurm-wlm and munge for --slurm and its test" >&2
    fi
  fi
  # Chart text (crates/report/src/lib.rs FONT_CANDIDATES, or $REPERTOIRE_FONT).
  local font
  for font in "${REPERTOIRE_FONT:-}" /usr/share/fonts/truetype/dejavu/DejaVuSans.ttf \
    /usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf /usr/share/fonts/TTF/DejaVuSans.ttf \
    /usr/share/fonts/dejavu/DejaVuSans.ttf; do
    [ -n "$font" ] && [ -f "$font" ] && return 0
  done
  local sudo=""
  [ "$(id -u)" = 0 ] || { command -v sudo >/dev/null && sudo -n true 2>/dev/null && sudo="sudo"; } || true
  if command -v apt-get >/dev/null && { [ "$(id -u)" = 0 ] || [ -n "$sudo" ]; }; then
    echo "setup: installing Debian's DejaVu fonts for chart text (apt-get install fonts-dejavu-core)" >&2
    $sudo apt-get update -qq >&2
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq fonts-dejavu-core >&2
  else
    echo "setup: no TrueType font for chart text; install fonts-dejavu-core or set REPERTOIRE_FONT to a .ttf" >&2
  fi
}

if [ -f "$lib" ] && [ -L "$lib_dir/libmujoco.so" ] && [ -f "$clips_dir/.complete" ] && bodies_ready; then
  web_and_browser
  exit 0
fi

command -v cargo >/dev/null || { echo "setup: cargo is not installed (https://rustup.rs)" >&2; exit 1; }
py="$(command -v python3 || command -v python || true)"
[ -n "$py" ] || { echo "setup: python3 with pip is needed to fetch the MuJoCo wheel" >&2; exit 1; }
"$py" -m pip --version >/dev/null 2>&1 || { echo "setup: pip is missing for $py" >&2; exit 1; }

tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT

# put(out, dest, data, digest, source): writes data to out/dest once its SHA-256 is the one
# expected; shared by the Python steps below (they import it from $tmp).
cat >"$tmp/checked.py" <<'PY'
import hashlib, sys
def put(out, dest, data, digest, source):
    got = hashlib.sha256(data).hexdigest()
    if got != digest:
        sys.exit(f"setup: {source} has SHA-256 {got}, expected {digest}")
    path = out / dest
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(data)
PY

# Moves a filled folder into place last, so an interrupted run never leaves it half filled.
into_place() {
  rm -rf "$2"
  mkdir -p "$(dirname "$2")"
  mv "$1" "$2"
  touch "$2/.complete"
}

if [ ! -f "$lib" ] || [ ! -L "$lib_dir/libmujoco.so" ]; then
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
fi

if [ ! -f "$clips_dir/.complete" ]; then
  echo "setup: fetching the clip pack (wheel 'pybullet==3.2.7', sdist 'bvhtoolbox==0.1.3')" >&2
  # Only data files are taken from the pybullet wheel, so the CPython 3.11 manylinux wheel serves
  # on any machine; the sdist of bvhtoolbox is pure source.
  "$py" -m pip download --quiet --no-deps --only-binary=:all: --python-version 3.11 \
    --platform manylinux2014_x86_64 --dest "$tmp/pybullet" "pybullet==3.2.7"
  "$py" -m pip download --quiet --no-deps --no-binary=:all: --dest "$tmp/bvhtoolbox" "bvhtoolbox==0.1.3"
  "$py" - "$tmp" "$tmp/clips" <<'PY'
import glob, pathlib, sys, tarfile, zipfile
tmp, out = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2])
sys.path.insert(0, str(tmp))
from checked import put
motions = "pybullet_data/data/motions/"
# destination in the pack: (archive member, SHA-256)
wanted = {
    "deepmimic/walk_forward.txt": (motions + "walker/0walk_forward.txt", "a8790c45361077ff07d99c3f00a1fa73b78ff3ec77d083188f13eac75dcc0a58"),
    "deepmimic/turn_left0.txt": (motions + "walker/turn_left0.txt", "5120bb55a4eb3ecfa75bcffcd472ad0b5be01647536f707896b9a9af655d6fce"),
    "deepmimic/turn_left1.txt": (motions + "walker/turn_left1.txt", "e78540dcccfad969ff1304182de293714c1db163096ee37a02dbf34930e0c3d0"),
    "deepmimic/turn_right0.txt": (motions + "walker/turn_right0.txt", "c1fa371a7d7d625970ad7fec0bb2d7ba59205acb74f8fac15f46799ae3a80ce3"),
    "deepmimic/turn_right1.txt": (motions + "walker/turn_right1.txt", "3a655a1e9334cef592b5b7bef4fd7a52e46fcacc8c7c807cfa1bee8249e6350d"),
    "deepmimic/humanoid3d_walk.txt": (motions + "humanoid3d_walk.txt", "32d082c3599bc40aac50b1afa196ff1e2cf3842bb40f0541ab088845f6328a41"),
    "deepmimic/humanoid3d_run.txt": (motions + "humanoid3d_run.txt", "2cbe488023b243e5769299158ce7c78875ec4b701a2ffe6c0beeaf83d16ca87b"),
}
sit = ("bvh/sit_down_stand_up.bvh", "bvhtoolbox-0.1.3/tests/example_files/test_mocapbank.bvh",
       "c12f37b39d931ee0bc8b081984255587eb8983e1d1a61fa0681ca6d5ea58e348")

wheel = glob.glob(str(tmp / "pybullet" / "pybullet-3.2.7-*.whl"))[0]
with zipfile.ZipFile(wheel) as z:
    for dest, (member, digest) in wanted.items():
        put(out, dest, z.read(member), digest, f"{wheel}:{member}")
sdist = glob.glob(str(tmp / "bvhtoolbox" / "bvhtoolbox-0.1.3.tar.gz"))[0]
with tarfile.open(sdist) as t:
    member = t.extractfile(sit[1])
    if member is None:
        sys.exit(f"setup: {sdist} has no {sit[1]}")
    put(out, sit[0], member.read(), sit[2], f"{sdist}:{sit[1]}")
PY
  into_place "$tmp/clips" "$clips_dir"
  echo "setup: clip pack installed in third_party/clips" >&2
fi

if ! bodies_ready; then
  echo "setup: fetching third-party bodies (wheels 'gymnasium==1.4.0', 'dm-control==1.0.52')" >&2
  "$py" -m pip download --quiet --no-deps --only-binary=:all: --dest "$tmp/gymnasium" "gymnasium==1.4.0"
  "$py" -m pip download --quiet --no-deps --only-binary=:all: --dest "$tmp/dm_control" "dm-control==1.0.52"
  "$py" - "$tmp" "$tmp/bodies" <<'PY'
import glob, pathlib, sys, zipfile
tmp, out = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2])
sys.path.insert(0, str(tmp))
from checked import put
# destination: (wheel glob, archive member, SHA-256)
wanted = {
    "gymnasium/humanoid.xml": ("gymnasium/gymnasium-1.4.0-*.whl", "gymnasium/envs/mujoco/assets/humanoid.xml",
                               "85816f372c826d2094b4a598918233bd9c5843b2439119eece2733bdc2e0d073"),
    "dm_control/humanoid_CMU_V2020.xml": ("dm_control/dm_control-1.0.52-*.whl",
                                          "dm_control/locomotion/walkers/assets/humanoid_CMU_V2020.xml",
                                          "bd115de99ad602c2160f8593c8ca7255a3920e2a30751f191b41200f225007f4"),
}
for dest, (pattern, member, digest) in wanted.items():
    wheel = glob.glob(str(tmp / pattern))[0]
    with zipfile.ZipFile(wheel) as z:
        put(out, dest, z.read(member), digest, f"{wheel}:{member}")
PY
  into_place "$tmp/bodies" "$bodies_dir"
  echo "setup: third-party bodies installed in third_party/bodies" >&2
fi

web_and_browser
