# Sourced by the other scripts: creates .venv with the pinned requirements
# and the project's package beamstop_tools (python/, installed editable, with
# its console scripts beamstop-sweep, beamstop-orbits and beamstop-report),
# again whenever requirements.txt or python/pyproject.toml changes, and
# activates it. The package's own dependencies (python/pyproject.toml) are
# requirements.txt's pins, installed here first (hence --no-deps).
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$root/.venv"
stamp="$venv/.requirements"
if [ ! -x "$venv/bin/python" ] || ! cat "$root/requirements.txt" "$root/python/pyproject.toml" | cmp -s - "$stamp"; then
    echo "setting up $venv (pinned requirements.txt, beamstop_tools editable)" >&2
    python3 -m venv "$venv"
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r "$root/requirements.txt"
    # The package's build backend is the pinned setuptools just installed.
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check --no-build-isolation --no-deps \
        -e "$root/python"
    cat "$root/requirements.txt" "$root/python/pyproject.toml" > "$stamp"
fi
# shellcheck disable=SC1091
source "$venv/bin/activate"
