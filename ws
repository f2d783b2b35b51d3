#!/usr/bin/env bash
# The workspace's one entry script. Every command first makes sure the workspace is set up (Debian's
# ROS 1 packages, a venv from /usr/bin/python3 with the pinned requirements, the catkin build) and
# does only what is missing, so a second run starts in seconds.
#
#   ./ws run [cube|hopper] [NAME:=VALUE ...]  set up, then train (roslaunch <robot's package> main.launch);
#                               rviz:=true also installs rviz (Debian's) and shows the robot in it;
#                               agent:=NAME of a deep agent (robot_rl.agents) also installs requirements-deep.txt;
#                               cluster:=ray|ADDRESS (env workers as Ray actors) also installs requirements-distributed.txt
#   ./ws rviz [cube|hopper] [NAME:=VALUE ...] set up with rviz, then the robot's sim running, seen in rviz
#   ./ws plot [NAMESPACE] [--output PNG]      a live plot of the reward topics (rqt_plot is not in Debian 12)
#   ./ws test [PYTEST ARGS]     set up, then the linters and every test (pytest + rostest)
#   ./ws test --quick [PYTEST ARGS]  pytest alone: no linters, no display packages, the deep agents' only if the tests use them
#   ./ws lint                   set up, then only the linters (ruff, mypy, catkin_lint, roslaunch-check)
#   ./ws bench [--reps N] [--sections S,...] [--running-step ROBOT=S] [--markdown]  set up (with the deep agents), then the benchmark (--markdown: also docs/reference/performance.md)
#   ./ws python [ARGS...]       python inside the workspace environment (the venv, the devel space)
#   ./ws exec CMD [ARGS...]     CMD inside the workspace environment
#   ./ws sweep [cube|hopper] [seeds:=0-9] [NAME:=V1,V2 ...] [max_steps:=N] [name:=SWEEP] [resume:=true] [cluster:=ray|ADDRESS]
#                               many training runs on Ray Tune, a table and a plot (installs requirements-distributed.txt)
#   ./ws cluster start|join ADDRESS|stop|status  this machine's Ray node (installs requirements-distributed.txt)
#   ./ws demo [cube|hopper] [policy:=NAME] [VIDEO.mp4]  a shipped trained policy (<package>/policies/NAME,
#                               default demo) plays one episode, recorded to VIDEO.mp4 (default ./demo_<robot>.mp4),
#                               then evaluate.py's JSON (a deep agent's policy also installs requirements-deep.txt)
#   ./ws setup [deep|distributed]  only the set-up (deep: also torch and stable-baselines3; distributed: also Ray)
#   ./ws help                   this text and the arguments of every launch file ./ws run starts
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
STATE="$ROOT/.ws"          # ignored by git; CATKIN_IGNORE keeps catkin out of it
VENV="$STATE/venv"
BUILD="$STATE/build"
DEVEL="$STATE/devel"
SYSTEM_PYTHON=/usr/bin/python3

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

# Installed only when asked for: rviz (./ws rviz, ./ws run ... rviz:=true, ./ws test), Tk for the reward
# plot's window (./ws plot, ./ws test) and, for the tests that need a display, Xvfb.
RVIZ_APT_PACKAGES=(rviz)
PLOT_APT_PACKAGES=(python3-tk)
TEST_APT_PACKAGES=(xvfb)

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
  # (docs/guide/training.md, "The same seed, the same run").
  # The Haswell kernels (AVX2 and FMA) give the same results on every machine that has AVX2.
  if grep -qw avx2 /proc/cpuinfo 2>/dev/null; then export OPENBLAS_CORETYPE="${OPENBLAS_CORETYPE:-Haswell}"; fi
  export ROBOT_RL_CLUSTER_DIR="${ROBOT_RL_CLUSTER_DIR:-$STATE/cluster}"  # ./ws cluster's node (robot_rl.cluster)
}

# The top-level launch file of each robot's training, as `./ws run ROBOT` starts it.
launch_of() {
  case "$1" in
    cube) echo "moving_cube_training main.launch" ;;
    hopper) echo "hopper_training main.launch" ;;
    *) die "unknown robot '$1' (known: cube, hopper; see ./ws help)" ;;
  esac
}

usage() {
  sed -n '2,/^set -euo pipefail$/{/^#/p}' "$0" | sed 's/^# \{0,1\}//'
}

# The usage, then each training launch file's arguments, as roslaunch itself lists them.
help_text() {
  usage
  local robot
  for robot in cube hopper; do
    # shellcheck disable=SC2046
    printf '\n./ws run %s = roslaunch %s, arguments (NAME:=VALUE):\n' "$robot" "$(launch_of "$robot")"
    # roslaunch files an argument whose default is "" under "Required": it is not, show its default.
    roslaunch --ros-args $(launch_of "$robot") | grep '^  ' | sed '/(default /!s/^\(  [^:]*\):/\1 (default ""):/' | sort
  done
  printf '\nResults go to %s/training_results/ (results_dir:=...).\n' "$ROOT"
}

# Every linter the tests rely on; stops at the first one that complains.
lint() {
  ensure_requirements requirements-dev.txt
  cd "$ROOT"
  log "ruff"
  ruff check --quiet . || die "ruff found problems (fix them, or 'ruff check --fix .')"
  log "mypy"
  mypy --no-error-summary || die "mypy found type errors"
  log "catkin_lint"
  local lint_output
  lint_output="$(catkin_lint --quiet . 2>&1 | grep -v "rosdep\|unknown dependencies" || true)"
  [ -z "$lint_output" ] || { echo "$lint_output" >&2; die "catkin_lint found problems"; }
  log "roslaunch-check"
  local launch_file
  for launch_file in pybullet_sim/launch/{cube,hopper}_sim.launch {moving_cube,hopper}_training/launch/main.launch \
                     moving_cube_training/launch/systems_test.launch test/rostest/*.test; do
    python3 /usr/share/roslaunch/scripts/roslaunch-check -o "$STATE/roslaunch-check.xml" "$launch_file" \
      | grep -q "^passed" || die "roslaunch-check: $launch_file has problems (see $STATE/roslaunch-check.xml)"
  done
}

free_port() {
  "$SYSTEM_PYTHON" -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

# A private master for commands that start their own (run, test), unless the caller chose one.
private_master() {
  if [ -z "${ROS_MASTER_URI:-}" ]; then
    export ROS_MASTER_URI="http://127.0.0.1:$(free_port)"
  fi
}

command="${1:-}"
[ $# -gt 0 ] && shift
case "$command" in
  setup)
    setup
    case "${1:-}" in
      deep|distributed) ensure_requirements "requirements-$1.txt" ;;
      "") ;;
      *) die "usage: ./ws setup [deep|distributed]" ;;
    esac ;;
  run)
    robot=cube
    if [ $# -gt 0 ] && [[ "$1" != *:=* && "$1" != -* ]]; then robot="$1"; shift; fi
    for arg in "$@"; do
      case "$arg" in
        -h|--help) setup; enter_environment; help_text; exit 0 ;;
        *:=*) ;;
        *) die "'$arg' is not a launch argument NAME:=VALUE (see ./ws help)" ;;
      esac
    done
    launch="$(launch_of "$robot")"
    setup
    agent="$(printf '%s\n' "$@" | sed -n 's/^agent:=//p' | tail -n 1)"
    if [ -n "$agent" ] && (enter_environment && python -m robot_rl.agents needs-deep "$agent"); then
      ensure_requirements requirements-deep.txt
    fi
    if printf '%s\n' "$@" | grep -qE '^cluster:=.'; then ensure_requirements requirements-distributed.txt; fi
    if printf '%s\n' "$@" | grep -qiE '^rviz:=(true|1)$'; then
      [ -n "${DISPLAY:-}" ] || die "rviz:=true needs a display (DISPLAY is not set)"
      ensure_apt_packages "${RVIZ_APT_PACKAGES[@]}"
    fi
    private_master
    enter_environment
    # shellcheck disable=SC2086
    exec rosrun workspace_tools roslaunch_checked.py $launch "results_dir:=$ROOT/training_results" "$@" ;;
  rviz)
    robot=cube
    if [ $# -gt 0 ] && [[ "$1" != *:=* ]]; then robot="$1"; shift; fi
    case "$robot" in cube|hopper) ;; *) die "unknown robot '$robot' (known: cube, hopper)" ;; esac
    [ -n "${DISPLAY:-}" ] || die "rviz needs a display (DISPLAY is not set)"
    setup
    ensure_apt_packages "${RVIZ_APT_PACKAGES[@]}"
    enter_environment
    exec roslaunch pybullet_sim "${robot}_sim.launch" rviz:=true paused:=false "$@" ;;
  plot)
    setup
    ensure_apt_packages "${PLOT_APT_PACKAGES[@]}"
    enter_environment
    exec rosrun robot_rl plot_rewards.py "$@" ;;
  help|-h|--help)
    setup
    enter_environment
    help_text ;;
  lint)
    setup
    enter_environment
    lint ;;
  test)
    quick=false
    if [ "${1:-}" = --quick ]; then quick=true; shift; fi
    cd "$ROOT"
    # The whole test folder unless the arguments name test files or folders themselves.
    paths=(test) named=()
    for arg in "$@"; do [[ "$arg" != -* && -e "${arg%%::*}" ]] && named+=("${arg%%::*}"); done
    [ ${#named[@]} -eq 0 ] || paths=()
    setup
    if [ "$quick" = true ]; then
      # pytest alone (requirements.txt has it): no linters, no display packages; the deep agents' packages only
      # for tests that use them.
      if grep -rlqE 'robot_rl\.deep|stable_baselines3|torch' --include='*.py' "${paths[@]}" "${named[@]}"; then
        ensure_requirements requirements-deep.txt
      fi
      if grep -rlqE '^ *(import ray|from ray)|robot_rl\.cluster|ray_cluster' --include='*.py' "${paths[@]}" "${named[@]}"; then
        ensure_requirements requirements-distributed.txt
      fi
    else
      ensure_apt_packages "${RVIZ_APT_PACKAGES[@]}" "${PLOT_APT_PACKAGES[@]}" "${TEST_APT_PACKAGES[@]}"
      ensure_requirements requirements-deep.txt
      ensure_requirements requirements-distributed.txt
    fi
    private_master
    enter_environment
    [ "$quick" = true ] || lint
    exec python -m pytest -p no:cacheprovider "$@" "${paths[@]}" ;;
  bench)
    setup
    ensure_requirements requirements-deep.txt
    ensure_requirements requirements-distributed.txt
    private_master
    enter_environment
    cd "$ROOT"
    exec rosrun workspace_tools bench.py "$@" ;;
  sweep)
    for arg in "$@"; do
      case "$arg" in -h|--help) setup; enter_environment; exec python -m workspace_tools.sweep --help ;; esac
    done
    setup
    agent="$(printf '%s\n' "$@" | sed -n 's/^agent:=//p' | tail -n 1)"
    if [ -n "$agent" ] && (enter_environment && python -m robot_rl.agents needs-deep "$agent"); then
      ensure_requirements requirements-deep.txt
    fi
    ensure_requirements requirements-distributed.txt
    enter_environment
    # Results go where ./ws run puts them unless results_dir:= says otherwise.
    printf '%s\n' "$@" | grep -q '^results_dir:=' || set -- "$@" "results_dir:=$ROOT/training_results"
    exec python -m workspace_tools.sweep "$@" ;;
  cluster)
    case "${1:-}" in
      start|stop|status) [ $# -eq 1 ] || [ "$1" = start ] || die "usage: ./ws cluster $1" ;;
      join) [ $# -ge 2 ] || die "usage: ./ws cluster join ADDRESS (HOST:PORT of the head)" ;;
      *) die "usage: ./ws cluster start|join ADDRESS|stop|status" ;;
    esac
    setup
    ensure_requirements requirements-distributed.txt
    enter_environment
    exec python -m robot_rl.cluster "$@" ;;
  demo)
    robot=hopper
    policy=demo
    if [ $# -gt 0 ] && [[ "$1" != *.mp4 && "$1" != policy:=* ]]; then robot="$1"; shift; fi
    if [ $# -gt 0 ] && [[ "$1" == policy:=* ]]; then policy="${1#policy:=}"; shift; fi
    case "$robot" in
      cube) package=moving_cube_training ;;
      hopper) package=hopper_training ;;
      *) die "unknown robot '$robot' (known: cube, hopper)" ;;
    esac
    [ $# -le 1 ] || die "usage: ./ws demo [cube|hopper] [policy:=NAME] [VIDEO.mp4]"
    shipped="$ROOT/$package/policies"
    if [[ ! "$policy" =~ ^[A-Za-z0-9_-]+$ ]] || [ ! -d "$shipped/$policy" ]; then
      die "no shipped policy '$policy' for $robot (known: $(ls "$shipped" | tr '\n' ' '| sed 's/ $//; s/ /, /g'))"
    fi
    video="$(realpath -m "${1:-demo_$robot.mp4}")"
    setup
    if [ -f "$shipped/$policy/agent.json" ]; then ensure_requirements requirements-deep.txt; fi
    enter_environment
    exec rosrun "$package" evaluate.py --run "$shipped/$policy" --episodes 1 --video "$video" \
      --video-episodes 1 ;;
  python)
    setup
    enter_environment
    exec python "$@" ;;
  exec)
    [ $# -gt 0 ] || die "usage: ./ws exec CMD [ARGS...]"
    setup
    enter_environment
    exec "$@" ;;
  *)
    usage >&2
    [ -z "$command" ] || die "unknown command '$command'"
    exit 2 ;;
esac
