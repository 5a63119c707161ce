#!/usr/bin/env bash
# The documentation site (`make docs`, docs/index.md): docs/ built by Debian's mkdocs with
# --strict into the build directory, without a warning, every page of docs/ in it, the generated
# configuration reference among them, and nothing written into the source tree.
# Usage: docs_site.sh SOURCE_DIR OUTPUT_DIR. Exit 77 (skipped) only when mkdocs is not installed.
set -euo pipefail
src=$1
out=$2
if ! command -v mkdocs >/dev/null 2>&1; then
  echo "DocsSite skipped: mkdocs is not installed (Debian package mkdocs; scripts/install-deps.sh installs it)"
  exit 77
fi
fail() {
  echo "DocsSite: $*"
  exit 1
}
before=$(cd "$src" && git status --porcelain --untracked-files=all 2>/dev/null || true)
rm -rf "$out"
log=$(mkdocs build --strict -f "$src/mkdocs.yml" -d "$out" 2>&1) || {
  echo "$log"
  fail "mkdocs build --strict failed"
}
echo "$log"
if grep -q -E "WARNING|ERROR" <<<"$log"; then fail "the build printed warnings"; fi
# mkdocs only mentions (INFO) pages left out of the navigation: every page must be in it.
if grep -q "not included in the \"nav\"" <<<"$log"; then fail "a page of docs/ is not in mkdocs.yml's nav"; fi
for md in "$src"/docs/*.md; do
  page=$(basename "$md" .md)
  [ -s "$out/$page.html" ] || fail "docs/$page.md was not rendered ($out/$page.html)"
  grep -q "href=\"$page.html\"" "$out/index.html" || fail "the navigation does not lead to $page.html"
done
# The generated reference: every configuration's section and a key of each.
for key in recognize reconstruct relocalize diff world texture camera_world min_confidence; do
  grep -q "$key" "$out/reference.html" || fail "reference.html lacks '$key'"
done
# Images referenced by the pages are copied along.
[ -s "$out/images/methods_carve_plots.png" ] || fail "the pages' images were not copied"
after=$(cd "$src" && git status --porcelain --untracked-files=all 2>/dev/null || true)
[ "$before" = "$after" ] || fail "the build wrote into the source tree: $after"
echo "DocsSite: $(ls "$out"/*.html | wc -l) pages in $out, no warning"
