# Bash completion for driftlab (installed as share/bash-completion/completions/driftlab).
#
# The verbs, options and option choices come from the program's own --help (CLI11's layout: "Subcommands:" lists
# the verbs, option lines start with "-", a choice reads TEXT:{a,b,c}), so they follow the program it completes
# for; each command's help is read once per shell. Everything else completes as file names (logs, scenarios,
# configs, output folders).

# _driftlab_help PROGRAM WORDS...: the help of `PROGRAM WORDS... --help` reduced to lines "sub NAME",
# "opt NAME" and "choice OPTION a b c", in _driftlab_reply; cached in _driftlab_cache.
_driftlab_help() {
  local key="$*"
  if [[ -z "${_driftlab_cache[$key]+set}" ]]; then
    _driftlab_cache[$key]=$("$@" --help 2>/dev/null | awk '
      /^[A-Z][A-Za-z ]*:$/ { section = $0; next }
      section == "Subcommands:" && /^  [a-z]/ { print "sub " $1; next }
      /^  -/ {
        n = split($1, names, ",")
        for (i = 1; i <= n; i++) print "opt " names[i]
        if (match($0, /:\{[^}]*\}/)) {
          choices = substr($0, RSTART + 2, RLENGTH - 3)
          gsub(/,/, " ", choices)
          for (i = 1; i <= n; i++) print "choice " names[i] " " choices
        }
      }')
  fi
  _driftlab_reply=${_driftlab_cache[$key]}
}

_driftlab() {
  COMPREPLY=()
  local cur=${COMP_WORDS[COMP_CWORD]} prev=${COMP_WORDS[COMP_CWORD - 1]}
  local program=${COMP_WORDS[0]}
  program=${program/#\~/$HOME}
  command -v "$program" >/dev/null 2>&1 || return 0
  declare -gA _driftlab_cache 2>/dev/null || return 0
  local _driftlab_reply

  # The command path so far: the words that name a subcommand of the one before.
  local -a path=("$program")
  local i word
  for ((i = 1; i < COMP_CWORD; i++)); do
    word=${COMP_WORDS[i]}
    [[ $word == -* ]] && continue
    _driftlab_help "${path[@]}"
    if [[ $'\n'$_driftlab_reply$'\n' == *$'\n'"sub $word"$'\n'* ]]; then path+=("$word"); fi
  done
  _driftlab_help "${path[@]}"
  local help=$_driftlab_reply

  local choices
  choices=$(awk -v o="$prev" '$1 == "choice" && $2 == o { $1 = ""; $2 = ""; print }' <<<"$help")
  if [[ -n $choices ]]; then
    mapfile -t COMPREPLY < <(compgen -W "$choices" -- "$cur")
    return 0
  fi
  if [[ $cur == -* ]]; then
    mapfile -t COMPREPLY < <(compgen -W "$(awk '$1 == "opt" { print $2 }' <<<"$help")" -- "$cur")
    return 0
  fi
  local subs
  subs=$(awk '$1 == "sub" { print $2 }' <<<"$help")
  if [[ -n $subs ]]; then mapfile -t COMPREPLY < <(compgen -W "$subs" -- "$cur"); fi
  # Logs, scenarios and folders: file names too, unless a subcommand must come first (driftlab's own verbs).
  if ((${#path[@]} > 1)) || [[ -z $subs ]]; then
    compopt -o filenames 2>/dev/null || true  # outside a completion (a test) there is nothing to set
    mapfile -t -O "${#COMPREPLY[@]}" COMPREPLY < <(compgen -f -- "$cur")
  fi
  return 0
}

complete -F _driftlab driftlab
