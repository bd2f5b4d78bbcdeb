# shellcheck shell=bash
# Sourced by the structure checks.

# layer_sources LAYER...: the layers' C++ sources (.h and .cpp in each layer's directory and
# its subdirectories one level down) into the array `files`, and the layers' names for the
# messages ("core/, kernels/ and formats/") into `layer_names`. A pattern that matches no
# file is left out, not passed on as a name.
layer_sources() {
  local dirs=("$@") d
  shopt -s nullglob
  files=()
  for d in "${dirs[@]}"; do files+=("$d"/*.{h,cpp} "$d"/*/*.{h,cpp}); done
  shopt -u nullglob
  layer_names=$(printf '%s/, ' "${dirs[@]}")
  layer_names=${layer_names%, }
  [ ${#dirs[@]} -gt 1 ] && layer_names="${layer_names%, *} and ${layer_names##*, }"
  return 0
}

# report OFFENDERS HEADING OK: the offenders (one per line) under "HEADING:" and exit 1 when
# there are any, else the line OK.
report() {
  if [ -n "$1" ]; then
    echo "$2:"
    echo "$1"
    exit 1
  fi
  echo "$3"
}
