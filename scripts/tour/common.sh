# Sourced by the tour scripts (scripts/tour/*.sh): `tour_init NAME DEFAULT_SUBDIR HELP_LAST_LINE "$@"`
# reads [--quick] [OUT_DIR], sets ROOT, QUICK, OUT and WEFT (absolute; OUT_DIR and WEFT as given,
# from the caller's directory), checks the weft binary, refuses an OUT that is neither empty nor an
# earlier output of a tour script (its info.txt starts with "started"), recreates it and cds to ROOT.
# `tour_started DETAILS` and `tour_finished` write OUT/info.txt.
# Environment: WEFT (default build/release/apps/weft), TOUR_QUICK=1 (same as --quick).
tour_init() {
  local name=$1 subdir=$2 help_last=$3 a
  shift 3
  ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
  QUICK=${TOUR_QUICK:-0}
  OUT=""
  for a in "$@"; do
    case "$a" in
      --quick) QUICK=1 ;;
      -h|--help) sed -n "2,${help_last}p" "$0"; exit 0 ;;
      -*) echo "$name: unknown option $a (usage: $name [--quick] [OUT_DIR])" >&2; exit 2 ;;
      *) OUT=$a ;;
    esac
  done
  OUT=${OUT:-$ROOT/out/tour/$subdir}
  WEFT=${WEFT:-$ROOT/build/release/apps/weft}
  case "$OUT" in /*) ;; *) OUT=$PWD/$OUT ;; esac
  case "$WEFT" in /*) ;; *) WEFT=$PWD/$WEFT ;; esac
  cd "$ROOT"
  [ -x "$WEFT" ] || { echo "$name: no weft binary at $WEFT (build it with scripts/setup.sh, or set WEFT)" >&2; exit 2; }
  if [ -d "$OUT" ] && [ -n "$(ls -A "$OUT")" ] && ! grep -qs "^started" "$OUT/info.txt"; then
    echo "$name: $OUT is not empty and not an output of this script: give a new or empty directory" >&2; exit 2
  fi
  rm -rf "$OUT"  # an earlier output of this script (its info.txt says so)
  mkdir -p "$OUT"
}

tour_started() {
  echo "started $(date -u +%FT%TZ); $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), $(nproc --all) CPUs; weft $WEFT; quick=$QUICK${*:+; $*}" > "$OUT/info.txt"
}

tour_finished() {
  echo "finished $(date -u +%FT%TZ)" >> "$OUT/info.txt"
}
