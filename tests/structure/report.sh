# Sourced by the structure checks. report OFFENDERS HEADING OK: the offenders (one per line)
# under "HEADING:" and exit 1 when there are any, else the line OK.
report() {
  if [ -n "$1" ]; then
    echo "$2:"
    echo "$1"
    exit 1
  fi
  echo "$3"
}
