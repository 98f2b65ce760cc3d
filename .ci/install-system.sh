#!/usr/bin/env bash
# System packages the tests need, from Debian's archive: Chromium for tests/integration/test_browser.py
# (driven by Playwright for Python, which must never download a browser of its own), and
# bubblewrap, the sandbox `lab grade` runs each student's notebook in (tests/integration/test_lab*.py),
# and nodejs (with npm), which installs MathJax from the npm registry when the book is built, so
# that its pages typeset offline (docs/_ext/book_assets.py).
# Idempotent, no prompts; run as root (or with passwordless sudo) on Debian.
set -euo pipefail

PACKAGES=(chromium fonts-dejavu-core bubblewrap nodejs)

missing=()
for package in "${PACKAGES[@]}"; do
    if ! dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q "install ok installed"; then
        missing+=("$package")
    fi
done
# Debian's nodejs has npm in a package of its own (NodeSource's nodejs includes it)
if ! command -v npm >/dev/null; then
    missing+=(npm)
fi
if [ "${#missing[@]}" -eq 0 ]; then
    echo "install-system: already installed: ${PACKAGES[*]}"
    exit 0
fi

SUDO=()
if [ "$(id -u)" -ne 0 ]; then
    command -v sudo >/dev/null || { echo "install-system: need root (or sudo) for apt-get" >&2; exit 1; }
    SUDO=(sudo -n)
fi
export DEBIAN_FRONTEND=noninteractive
"${SUDO[@]}" apt-get update -q
"${SUDO[@]}" apt-get install -y -q "${missing[@]}"
/usr/bin/chromium --version
