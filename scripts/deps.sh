#!/usr/bin/env bash
# Install what msid needs on Debian bookworm, only where it is missing.
# Called by ./bootstrap.sh; safe to run again.
set -euo pipefail

APT_PKGS=(build-essential cmake pkg-config libcmocka-dev libfftw3-dev
          nlohmann-json3-dev libeigen3-dev python3 python3-pip)
PY_MODS=(numpy jsonschema pytest)

as_root() { if [ "$(id -u)" = 0 ]; then "$@"; elif command -v sudo >/dev/null; then sudo "$@"; else
  echo "deps: need root (or sudo) to run: $*" >&2; return 1; fi; }

missing=()
for p in "${APT_PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "deps: installing ${missing[*]} (log: deps.log)"
  export DEBIAN_FRONTEND=noninteractive
  { as_root apt-get update -qq && as_root apt-get install -y -qq --no-install-recommends "${missing[@]}"; } \
    >> deps.log 2>&1 || { tail -30 deps.log; echo "deps: apt-get failed (see deps.log)" >&2; exit 1; }
fi

py_missing() { local m out=(); for m in "${PY_MODS[@]}"; do
  python3 -c "import $m" 2>/dev/null || out+=("$m"); done; echo "${out[*]:-}"; }
need=$(py_missing)
if [ -n "$need" ]; then
  # Debian's own python3 takes Debian packages; any other python3 on PATH (pyenv, venv) takes pip.
  if [ "$(command -v python3)" = /usr/bin/python3 ]; then
    pk=(); for m in $need; do pk+=("python3-$m"); done
    export DEBIAN_FRONTEND=noninteractive
    as_root apt-get install -y -qq --no-install-recommends "${pk[@]}" >> deps.log 2>&1 || true
  fi
  need=$(py_missing)
  if [ -n "$need" ]; then
    echo "deps: pip installing $need"
    python3 -m pip install -q $need >> deps.log 2>&1 || {
      tail -20 deps.log; echo "deps: pip install $need failed (see deps.log)" >&2; exit 1; }
  fi
fi
need=$(py_missing)
[ -z "$need" ] || { echo "deps: python modules still missing: $need" >&2; exit 1; }
