# Sourced by the other scripts: create or reuse .venv at the repo root and install the project.
# Usage: source scripts/setup.sh [extras]   (extras: "" or "test")
# The Python: $PYTHON if set, else the newest supported one found (python3.N on the PATH, or a
# pyenv-installed 3.N); an existing .venv is reused when its Python is supported.
set -euo pipefail
repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$repo_root"

# The supported minor versions, from pyproject.toml's requires-python = ">=3.L,<3.H".
read -r low high < <(sed -n 's/^requires-python = ">=3\.\([0-9]*\),<3\.\([0-9]*\)".*/\1 \2/p' pyproject.toml)

supported() {  # whether "$1" runs and is a supported Python
    "$1" -c "import sys; sys.exit(not (3, $low) <= sys.version_info[:2] < (3, $high))" >/dev/null 2>&1
}

candidates() {  # python3.$1 on the PATH, then pyenv's 3.$1 installs, newest first
    echo "python3.$1"
    if command -v pyenv >/dev/null 2>&1; then
        ls -d "$(pyenv root)"/versions/3."$1".*/bin/python3."$1" 2>/dev/null | sort -V -r
    fi
}

newest_python() {  # the newest supported Python found, or nothing
    local minor candidate
    for ((minor = high - 1; minor >= low; minor--)); do
        while read -r candidate; do
            if supported "$candidate"; then echo "$candidate"; return; fi
        done < <(candidates "$minor")
    done
}

if [ -x .venv/bin/python ]; then
    if ! supported .venv/bin/python; then
        echo "error: .venv has an unsupported Python ($(.venv/bin/python -V 2>&1)); remove .venv" >&2
        exit 1
    fi
    if [ -n "${PYTHON:-}" ] && [ "$("$PYTHON" -V 2>&1)" != "$(.venv/bin/python -V 2>&1)" ]; then
        echo "error: .venv has $(.venv/bin/python -V 2>&1), PYTHON is $("$PYTHON" -V 2>&1); remove .venv to switch" >&2
        exit 1
    fi
else
    python_bin="${PYTHON:-$(newest_python)}"
    if [ -z "$python_bin" ] || ! supported "$python_bin"; then
        echo "error: GNP Lab needs Python 3.$low to 3.$((high - 1)) (set PYTHON=/path/to/python3)" >&2
        exit 1
    fi
    echo "setup: creating .venv with $python_bin ($("$python_bin" -V 2>&1))" >&2
    "$python_bin" -m venv .venv
fi

extras="${1:-}"
stamp=".venv/.gnp-lab-installed${extras:+-$extras}"
# Reinstall only when the dependency list changed since the last install.
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ]; then
    echo "setup: installing gnp-lab${extras:+[$extras]} into .venv" >&2
    .venv/bin/python -m pip install --quiet --upgrade pip
    .venv/bin/python -m pip install --quiet -e ".${extras:+[$extras]}"
    touch "$stamp"
fi
export PATH="$repo_root/.venv/bin:$PATH"
