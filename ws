#!/usr/bin/env bash
# The workspace's one entry script: it sets up what must be there before Python can run (Debian's ROS 1
# packages, a venv from /usr/bin/python3 with the pinned requirements, the catkin build, the environment),
# doing only what is missing, then hands the command to ./ws's Python CLI (workspace_tools/src/workspace_tools/
# cli.py), which first says what else the command needs installed (`cli needs COMMAND ARGS...`: rviz, Tk,
# Xvfb, requirements-deep.txt, requirements-distributed.txt, requirements-dev.txt, a private master).
# `./ws help` lists the commands.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
STATE="$ROOT/.ws"          # ignored by git; CATKIN_IGNORE keeps catkin out of it
VENV="$STATE/venv"
BUILD="$STATE/build"
DEVEL="$STATE/devel"
SYSTEM_PYTHON=/usr/bin/python3
# The caller's ROS master, if it chose one (ROS_MASTER_URI set): it wins. Without it ./ws run takes port 11311
# (another if taken) and ./ws plot, rviz and exec join the run going on (workspace_tools.cli, live_runs).
export WS_CALLER_MASTER="${ROS_MASTER_URI:-}"

# Debian 12's ROS 1 (ROS is not on PyPI) and the build tools catkin needs.
APT_PACKAGES=(
  ros-core rosbash catkin cmake g++ make python3-venv python3-catkin-pkg
  python3-rospy python3-roslaunch python3-rostest python3-rosunit
  python3-tf python3-tf2-ros ros-robot-state-publisher
  ros-message-generation ros-message-runtime python3-genpy
  python3-std-msgs ros-std-msgs python3-std-srvs ros-std-srvs
  python3-geometry-msgs ros-geometry-msgs python3-sensor-msgs ros-sensor-msgs
  python3-nav-msgs ros-nav-msgs python3-rosgraph-msgs ros-rosgraph-msgs
  python3-tf2-msgs ros-tf2-msgs tf-tools librostest-dev libsensor-msgs-dev libnav-msgs-dev
  python3-visualization-msgs ros-visualization-msgs
)

log() { echo "[ws] $*" >&2; }
die() { echo "[ws] error: $*" >&2; exit 1; }

as_root() {
  if [ "$(id -u)" = 0 ]; then "$@"; elif command -v sudo >/dev/null; then sudo "$@"; else
    die "installing Debian packages needs root (or sudo): $*"; fi
}

# Install the Debian packages named (default: APT_PACKAGES) that are not installed yet.
ensure_apt_packages() {
  local packages=("$@") missing=() pkg
  [ ${#packages[@]} -gt 0 ] || packages=("${APT_PACKAGES[@]}")
  local installed
  installed="$(dpkg-query -W -f='${Package} ${db:Status-Abbrev}\n' "${packages[@]}" 2>/dev/null || true)"
  for pkg in "${packages[@]}"; do
    grep -q "^$pkg ii" <<<"$installed" || missing+=("$pkg")
  done
  [ ${#missing[@]} -eq 0 ] && return
  log "installing Debian packages: ${missing[*]}"
  as_root apt-get update -qq
  as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
}

ensure_venv() {
  if [ ! -x "$VENV/bin/python" ]; then
    log "creating the venv (from $SYSTEM_PYTHON, with Debian's site-packages for rospy)"
    "$SYSTEM_PYTHON" -m venv --system-site-packages "$VENV"
  fi
  ensure_requirements requirements.txt
}

# Install a pinned requirements file into the venv unless this very file was installed before.
ensure_requirements() {
  local file="$1" stamp wanted
  stamp="$VENV/.${file%.txt}.sha256"
  wanted="$(sha256sum "$ROOT/$file" | cut -d' ' -f1)"
  if [ "$(cat "$stamp" 2>/dev/null)" != "$wanted" ]; then
    log "installing $file into the venv"
    "$VENV/bin/pip" install --disable-pip-version-check -q -r "$ROOT/$file" 2>&1 | grep -v "^WARNING: Location" >&2 || true
    "$VENV/bin/pip" install --disable-pip-version-check -q --no-deps -r "$ROOT/$file" >/dev/null 2>&1 \
      || die "pip could not install $file (run: $VENV/bin/pip install -r $ROOT/$file)"
    echo "$wanted" >"$stamp"
  fi
}

ensure_catkin_build() {
  mkdir -p "$STATE"
  touch "$STATE/CATKIN_IGNORE"
  # The repository root is the catkin source space; catkin_make would create this same symlink.
  [ -e "$ROOT/CMakeLists.txt" ] || ln -s /usr/share/catkin/cmake/toplevel.cmake "$ROOT/CMakeLists.txt"
  # Re-configure when the set of packages changes (catkin finds packages at configure time).
  local packages stamp="$BUILD/.packages.sha256"
  packages="$(cd "$ROOT" && { find . -name package.xml -not -path './.ws/*' | sort | xargs sha256sum; echo "$VENV"; } \
    | sha256sum | cut -d' ' -f1)"
  if [ ! -f "$BUILD/Makefile" ] || [ "$(cat "$stamp" 2>/dev/null)" != "$packages" ]; then
    log "configuring the catkin build"
    mkdir -p "$BUILD"
    # The venv's python is Debian's /usr/bin/python3 with the pinned PyPI packages beside Debian's
    # site-packages: the scripts catkin installs (devel and install space) start with it.
    cmake -S "$ROOT" -B "$BUILD" -DCATKIN_DEVEL_PREFIX="$DEVEL" -DPYTHON_EXECUTABLE="$VENV/bin/python3" \
      -DCATKIN_ENABLE_TESTING=OFF -DCMAKE_BUILD_TYPE=Release >"$BUILD/configure.log" 2>&1 \
      || { cat "$BUILD/configure.log" >&2; die "catkin configure failed (log above)"; }
    echo "$packages" >"$stamp"
  fi
  make -C "$BUILD" -j"$(nproc)" >"$BUILD/make.log" 2>&1 || { cat "$BUILD/make.log" >&2; die "catkin build failed (log above)"; }
}

setup() {
  ensure_apt_packages
  ensure_venv
  ensure_catkin_build
}

# The environment every command runs in: devel space + venv; ROS on loopback unless the caller chose.
enter_environment() {
  set +u
  # shellcheck disable=SC1091
  source "$DEVEL/setup.bash"
  set -u
  export VIRTUAL_ENV="$VENV"
  export PATH="$VENV/bin:$PATH"
  export ROS_MASTER_URI="${ROS_MASTER_URI:-http://127.0.0.1:11311}"
  export ROS_HOSTNAME="${ROS_HOSTNAME:-127.0.0.1}"
  # C++ nodes (rosout, robot_state_publisher) bind to ROS_IP, not ROS_HOSTNAME: both keep a run on loopback.
  export ROS_IP="${ROS_IP:-127.0.0.1}"
  export PYTHONDONTWRITEBYTECODE=1
  # numpy's OpenBLAS picks its kernels by CPU, and an AVX-512 machine's round differently in the last bit: the
  # hop cycle's small matrix products then set chaotic hopping on another course
  # (docs/training.md, "The same seed, the same run").
  # The Haswell kernels (AVX2 and FMA) give the same results on every machine that has AVX2.
  if grep -qw avx2 /proc/cpuinfo 2>/dev/null; then export OPENBLAS_CORETYPE="${OPENBLAS_CORETYPE:-Haswell}"; fi
  export ROBOT_RL_CLUSTER_DIR="${ROBOT_RL_CLUSTER_DIR:-$STATE/cluster}"  # ./ws cluster's node (robot_rl.workers.cluster)
}

free_port() {
  "$SYSTEM_PYTHON" -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

# A private master for commands that start their own (test, bench), unless the caller chose one.
private_master() {
  if [ -z "${ROS_MASTER_URI:-}" ]; then
    export ROS_MASTER_URI="http://127.0.0.1:$(free_port)"
  fi
}

cli() { python -m workspace_tools.cli "$@"; }

# One ./ws sets up at a time: two makes in one build folder break each other's configure. The lock is let go
# before the command runs, so that a long run never holds up another terminal's ./ws.
mkdir -p "$STATE"
exec {setup_lock}>"$STATE/setup.lock"
flock -w 10 "$setup_lock" || { log "waiting for another ./ws to finish its setup (apt, pip, the catkin build)"
  flock "$setup_lock"; }
setup
# What the command needs besides: one line each, `apt PACKAGE`, `requirements FILE` or `private-master`; a
# command or argument the CLI refuses ends here, with its message and exit code.
needs="$(enter_environment && cli needs "$@")" || exit $?
apt_packages=()
while read -r kind value; do
  case "$kind" in
    apt) apt_packages+=("$value") ;;
    requirements) ensure_requirements "$value" ;;
    private-master) private_master ;;
  esac
done <<<"$needs"
[ ${#apt_packages[@]} -eq 0 ] || ensure_apt_packages "${apt_packages[@]}"
exec {setup_lock}>&-
enter_environment
exec python -m workspace_tools.cli "$@"
