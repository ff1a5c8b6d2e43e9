# shellcheck shell=bash disable=SC2154,SC2034  # script and bin are the sourcing test's; failed is read by it
# Sourced by the tests of scripts/ that take --bin (slam_robustness_test.sh, check_relations_test.sh): `expect
# MESSAGE ARGS...` runs "$script" --bin "$bin" ARGS in the current folder and wants exit status 2 and exactly one
# line on stderr, containing MESSAGE; otherwise it says so and sets failed=1.
failed=0
expect() {
  local want=$1
  shift
  "$script" --bin "$bin" "$@" >out.txt 2>err.txt
  local status=$?
  if [[ $status -ne 2 || $(wc -l <err.txt) -ne 1 ]] || ! grep -qF -- "$want" err.txt; then
    echo "FAILED: $(basename "$script") $*: exit $status, wanted 2 and one line with '$want'; stderr:"
    cat err.txt
    failed=1
  fi
}
