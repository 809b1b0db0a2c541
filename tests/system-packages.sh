#!/usr/bin/env bash
# The Debian/Ubuntu packages the test suite needs beyond Python: a redis-server for the Redis state
# store's tests, mosquitto for the MQTT tests of push (tests/test_push.py) and Chromium for the browser
# tests (Playwright drives the system's chromium and downloads no browser of its own). Installs only
# what is missing: as root directly, else with sudo.
set -euo pipefail
missing=()
command -v redis-server >/dev/null 2>&1 || missing+=(redis-server)
[ -x /usr/sbin/mosquitto ] || missing+=(mosquitto)
[ -x /usr/bin/chromium ] || missing+=(chromium)
[ ${#missing[@]} -eq 0 ] && exit 0
as_root=""
[ "$(id -u)" -eq 0 ] || as_root="sudo"
echo "+ $as_root apt-get install -y ${missing[*]}"
$as_root env DEBIAN_FRONTEND=noninteractive apt-get update -qq
$as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}"
