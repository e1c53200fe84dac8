#!/usr/bin/env bash
# Headless rendering for MuJoCo's own renderer on a machine with no display (EGL / OSMesa from
# Debian). Optional: without it, jgrounding.render falls back to matplotlib.
set -u
need=()
for lib in libEGL.so.1 libOSMesa.so.8 libGL.so.1; do
  ldconfig -p 2>/dev/null | grep -q "$lib" || need+=("$lib")
done
[ ${#need[@]} -eq 0 ] && exit 0
command -v apt-get >/dev/null 2>&1 || exit 1
SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo -n"
$SUDO apt-get update -qq >/dev/null 2>&1 || true
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq libegl1 libosmesa6 libgl1 libglx-mesa0 libegl-mesa0 >/dev/null 2>&1
