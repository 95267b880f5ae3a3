#!/usr/bin/env bash
# Build the API reference from the sources (issue 28): the public C headers
# through Doxygen (docs/api/Doxyfile) into build/docs/c/html, and the Python
# client through pdoc into build/docs/python (or under $NTS_DOCS_DIR). Exits
# non-zero on any Doxygen warning (an undocumented public declaration, a
# broken doc command), so the reference never silently leaves part of the API
# out; tests/python/test_api_docs.py checks the same, and the Python side.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
out=${NTS_DOCS_DIR:-build/docs}
rm -rf "$out/c" "$out/python"
mkdir -p "$out/c"
log="$out/c/doxygen-warnings.log"

# The Doxyfile's own output and log settings are overridden here (later lines
# win), so that the test can run the same file into a temporary directory.
set +e
{ cat docs/api/Doxyfile; printf 'OUTPUT_DIRECTORY = "%s"\nWARN_LOGFILE = "%s"\n' "$out/c" "$log"; } | doxygen -
rc=$?
set -e
if [ "$rc" -ne 0 ] || [ -s "$log" ]; then
  echo "docs: doxygen failed (exit $rc); its warnings ($log):" >&2
  cat "$log" >&2
  exit 1
fi

# pdoc documents a package's __all__ and not its other submodules, so each
# public module (not starting with '_') is named; the package comes from this
# checkout. A name both in __all__ and a submodule (ntscontact.plot, the
# function and its module) is then named twice: pdoc keeps one page and says
# so, which is no fault, hence the -W filter.
modules=(ntscontact)
for f in clients/python/src/ntscontact/*.py; do
  m=$(basename "$f" .py)
  [[ $m == _* ]] || modules+=("ntscontact.$m")
done
PYTHONPATH="$PWD/clients/python/src${PYTHONPATH:+:$PYTHONPATH}" \
  .venv/bin/python -W "ignore:The module specification" -m pdoc --docformat restructuredtext -o "$out/python" "${modules[@]}"

echo "docs: C API reference:      $out/c/html/index.html"
echo "docs: Python API reference: $out/python/index.html"
