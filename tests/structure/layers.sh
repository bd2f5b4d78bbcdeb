#!/usr/bin/env bash
# Dependencies point one way: service -> formats, kernels -> core. Each layer's sources
# include project headers only from the layers below it (CMake links the same way).
# Usage: layers.sh SOURCE_DIR
set -euo pipefail
cd "${1:?source dir}"
status=0
check() {  # check LAYER ALLOWED_REGEX
  local bad
  bad=$(grep -rnE '^\s*#\s*include\s+"(core|kernels|formats|service)/' "$1" --include='*.h' --include='*.cpp' |
        grep -vE "#\s*include\s+\"($2)/" || true)
  if [ -n "$bad" ]; then
    echo "$1/ includes a layer it must not use (allowed: $2):"
    echo "$bad"
    status=1
  fi
}
check core 'core'
check kernels 'core|kernels'
check formats 'core|formats'
check service 'core|kernels|formats|service'
[ $status = 0 ] && echo "core <- kernels, core <- formats, {core, kernels, formats} <- service: every include follows the layers"
exit $status
