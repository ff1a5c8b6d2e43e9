#!/usr/bin/env bash
# scripts/check-layers on a scratch work tree holding docs/architecture.md: it passes on an include the table
# allows, and fails, naming the file and line, on an arrow the table forbids, another folder's internal/ header, a
# folder without a row, a stale exception and a table with a cycle; and a test file outside tests/apps/ that runs
# the program unlisted, or listed and no longer running it.
#   tests/check_layers_test.sh SOURCE_DIR
set -euo pipefail
source=$(realpath "$1")
check=$source/scripts/check-layers
tmp=$(mktemp -d /tmp/driftlab-layers-test-XXXXXX)
trap 'rm -rf "$tmp"' EXIT
cd "$tmp"
git init -q .
mkdir -p docs core replayer analyzers/internal tests/analyzers
cp "$source/docs/architecture.md" docs/
echo '#include "core/time.h"' >replayer/a.cc
echo '#include "analyzers/internal/x.h"' >tests/analyzers/a_test.cc
# The doc's exceptions, each needed once: copied from the real tree.
sed -n 's/^- `\([^`]*\)` -> `\([^`]*\)`: .*/\1 \2/p' docs/architecture.md | while read -r file header; do
  mkdir -p "$(dirname "$file")" && echo "#include \"$header\"" >>"$file"
done
# The tests the doc lists as running the program, each running it.
sed -n 's/^- `\(tests\/[^`]*\)`: .*/\1/p' docs/architecture.md | while read -r file; do
  mkdir -p "$(dirname "$file")" && echo 'const std::string kDriftlab = "driftlab";' >>"$file"
done
"$check" --root "$tmp" || { echo "the allowed includes were refused"; exit 1; }

expect_refused() {  # WHAT PATTERN: the check fails and says PATTERN
  if out=$("$check" --root "$tmp" 2>&1); then echo "not refused: $1"; exit 1; fi
  grep -q -- "$2" <<<"$out" || { echo "refused without naming $1 ($2):"; echo "$out"; exit 1; }
}
echo '#include "analyzers/timing.h"' >>replayer/a.cc
expect_refused "the replayer including the analyzers" "replayer/a.cc:2: includes analyzers/timing.h, but \`replayer/\` may not include \`analyzers/\`"
echo '#include "core/time.h"' >replayer/a.cc
echo '#include "analyzers/internal/x.h"' >replayer/b.cc
expect_refused "another folder's internal header" "replayer/b.cc:1: includes analyzers/internal/x.h, internal to analyzers/"
rm replayer/b.cc
mkdir -p newfolder && echo '#include "core/time.h"' >newfolder/c.cc
expect_refused "a folder without a row" "newfolder/c.cc:1: \`newfolder/\` has no row"
rm -r newfolder
# An exception whose file no longer needs it: stale.
mkdir -p core && echo '#include "core/time.h"' >core/log_index.cc
sed -i 's/^No file is an exception to the table\./- `core\/log_index.cc` -> `lcmtypes\/stream_header.h`: kept after the include went./' docs/architecture.md
grep -q '^- `core/log_index.cc` -> ' docs/architecture.md || { echo "the test could not add an exception"; exit 1; }
expect_refused "a stale exception" "no longer needed: remove it"
rm core/log_index.cc
cp "$source/docs/architecture.md" docs/
# lcmtypes may include core; core may include lcmtypes too: a cycle.
sed -i 's/^| `core\/` | |$/| `core\/` | `lcmtypes\/` |/' docs/architecture.md
expect_refused "a cycle" "the table has a cycle: "
cp "$source/docs/architecture.md" docs/
echo 'run(std::string(DRIFTLAB_BIN_DIR) + "/driftlab info x.lcm");' >tests/analyzers/a_test.cc
expect_refused "an unlisted test running the program" "tests/analyzers/a_test.cc: runs the driftlab program"
echo '' >tests/analyzers/a_test.cc
echo '// no program here' >tests/formats/bombs_test.cc
expect_refused "a listed test no longer running the program" "tests/formats/bombs_test.cc no longer runs it"
echo "check-layers refuses what it must"
