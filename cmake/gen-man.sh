#!/usr/bin/env bash
# Writes the man pages of driftlab from its own --help, with help2man: driftlab.1, and driftlab-VERB.1 for every
# verb `driftlab --help` lists (as git's git-VERB pages), into OUTDIR. Run by the build (apps/CMakeLists.txt).
#   cmake/gen-man.sh DRIFTLAB OUTDIR
set -euo pipefail
bin=$1 out=$2
version=$("$bin" --version)
mkdir -p "$out"
rm -f "$out"/*.1
page() {  # page NAME DESCRIPTION WORDS...: NAME.1 from `DRIFTLAB WORDS... --help`
  local name=$1 description=$2
  shift 2
  help2man --no-info --section 1 --source "driftlab $version" --version-string "$name $version" \
    --name "$description" --help-option "$* --help" --output "$out/$name.1" "$bin"
}
page driftlab "record, replay and diagnose robot logs"
"$bin" --help | sed -n '/^Subcommands:/,$p' | awk 'NR > 1 && NF' | while read -r verb description; do
  # help2man reads --name as roff; a description is one sentence, its full stop dropped.
  page "driftlab-$verb" "${description%.}" "$verb"
done
