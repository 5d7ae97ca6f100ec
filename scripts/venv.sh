# Sourced by the other scripts: creates .venv with the pinned requirements
# (again whenever requirements.txt changes) and activates it.
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$root/.venv"
stamp="$venv/.requirements"
if [ ! -x "$venv/bin/python" ] || ! cmp -s "$root/requirements.txt" "$stamp"; then
    echo "setting up $venv (pinned requirements.txt)" >&2
    python3 -m venv "$venv"
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r "$root/requirements.txt"
    cp "$root/requirements.txt" "$stamp"
fi
# shellcheck disable=SC1091
source "$venv/bin/activate"
