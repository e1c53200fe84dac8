#!/usr/bin/env bash
# System packages from Debian, installed by `make install`:
# - headless rendering for MuJoCo's own renderer on a machine with no display (EGL / OSMesa); optional:
#   without it, jgrounding.render falls back to matplotlib;
# - the browser the page's test drives (tests/serving/test_page.py): chromium and chromium-driver, so
#   Selenium downloads nothing. In CI (CI=true) that test fails when they are missing;
# - the PostgreSQL server the study's store tests start themselves (tests/study/conftest.py): Debian 12's
#   postgresql (postgresql-15: /usr/lib/postgresql/15/bin/initdb and pg_ctl, and the postgres user they run as
#   under root). Without it those tests skip, saying why; SQLite is tested either way.
set -u
pkgs=()
for lib in libEGL.so.1 libOSMesa.so.8 libGL.so.1; do
  ldconfig -p 2>/dev/null | grep -q "$lib" || { pkgs+=(libegl1 libosmesa6 libgl1 libglx-mesa0 libegl-mesa0); break; }
done
[ -x /usr/bin/chromium ] && [ -x /usr/bin/chromedriver ] || pkgs+=(chromium chromium-driver)
[ -x /usr/lib/postgresql/15/bin/initdb ] && [ -x /usr/lib/postgresql/15/bin/pg_ctl ] || pkgs+=(postgresql)
[ ${#pkgs[@]} -eq 0 ] && exit 0
command -v apt-get >/dev/null 2>&1 || exit 1
SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo -n"
$SUDO apt-get update -qq >/dev/null 2>&1 || true
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${pkgs[@]}" >/dev/null 2>&1
