# shellcheck shell=bash
# Helpers of the benchmark scripts (sourced by them, not run).

# The median of the numbers on stdin, one per line.
median() { sort -g | awk '{a[NR]=$1} END {print (NR%2) ? a[(NR+1)/2] : (a[NR/2]+a[NR/2+1])/2}'; }

# Stage $1's figure (read, compute, write) from each line `ssdo process -v` prints per frame
# ("... read R ms, compute C ms, write W ms, ...") on stdin.
stage() { sed -n "s/.* $1 \([0-9.]*\) ms.*/\1/p"; }
