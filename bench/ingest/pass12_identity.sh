#!/usr/bin/env bash
# Passes 1-2 identity check: ingests one input (`--no-pyramid`, extra options passed on) with two
# tinstream binaries and compares the stored tiles (sha256 over z/x/y and blob, (z, x, y) order),
# `tinstream info` (counts, bounds; created_unix left out) and the ingest's summary lines
# (records, duplicates merged). Prints SAME or DIFF with the differences.
#   bench/ingest/pass12_identity.sh OLD_BIN NEW_BIN NAME INPUT... [OPTIONS...]
set -u
OLD=$(realpath "$1")
NEW=$(realpath "$2")
NAME=$3
shift 3
WORK=${WORK:-/tmp/tinstream-pass12-identity}
mkdir -p "$WORK"
for which in old new; do
  BIN=$OLD
  [ "$which" = new ] && BIN=$NEW
  DB="$WORK/$NAME-$which.db"
  rm -f "$DB"*
  nice -n 10 "$BIN" ingest --store "$DB" --layer t --no-pyramid -q "$@" >"$WORK/$NAME-$which.out" 2>&1 ||
    echo "$which failed: $(tail -2 "$WORK/$NAME-$which.out")"
  python3 - "$DB" >"$WORK/$NAME-$which.hash" <<'PY'
import hashlib, sqlite3, sys
db = sqlite3.connect(sys.argv[1])
version = db.execute("SELECT version FROM layers WHERE name = 't'").fetchone()[0]
digest, n = hashlib.sha256(), 0
for z, x, y, data in db.execute(
        "SELECT z, x, y, data FROM tiles WHERE version = ? ORDER BY z, x, y", (version,)):
    digest.update(f"{z}/{x}/{y}:".encode())
    digest.update(data)
    n += 1
print(n, digest.hexdigest())
PY
  "$OLD" info --store "$DB" --layer t | grep -v created_unix >"$WORK/$NAME-$which.info"
  grep -E "records|layer|level" "$WORK/$NAME-$which.out" >"$WORK/$NAME-$which.summary"
  rm -f "$DB"*
done
same=1
for part in hash info summary; do
  cmp -s "$WORK/$NAME-old.$part" "$WORK/$NAME-new.$part" || {
    same=0
    diff "$WORK/$NAME-old.$part" "$WORK/$NAME-new.$part" | head
  }
done
if [ $same = 1 ]; then echo "SAME $NAME $(cat "$WORK/$NAME-new.hash")"; else echo "DIFF $NAME"; fi
