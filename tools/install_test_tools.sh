#!/usr/bin/env bash
# Debian's tshark (Wireshark's CANopen dissector reads the traces) and chromium (renders the
# report headless), for the tests that use them; nothing happens where both are there already.
# Always exits 0: where they cannot be installed, the tests that use them are skipped.
missing=()
command -v tshark >/dev/null || missing+=(tshark)
command -v chromium >/dev/null || missing+=(chromium)
[ ${#missing[@]} -eq 0 ] && exit 0
sudo=""; [ "$(id -u)" -ne 0 ] && sudo="sudo -n"
export DEBIAN_FRONTEND=noninteractive
if command -v apt-get >/dev/null && { $sudo apt-get install -y -q "${missing[@]}" >/dev/null 2>&1 ||
        { $sudo apt-get update -q >/dev/null 2>&1 && $sudo apt-get install -y -q "${missing[@]}" >/dev/null 2>&1; }; }; then
    exit 0
fi
echo "install_test_tools: could not install ${missing[*]}: the tests that use them are skipped" >&2
exit 0
