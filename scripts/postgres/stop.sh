#!/usr/bin/env bash
# Stops the PostgreSQL that scripts/postgres/start.sh started in DIR and deletes DIR.
set -euo pipefail
DIR="$1"
bin=""
for d in /usr/lib/postgresql/*/bin; do [ -x "$d/pg_ctl" ] && bin="$d"; done
as=()
if [ "$(id -u)" = 0 ]; then as=(runuser -u postgres --); fi
"${as[@]}" "$bin/pg_ctl" -D "$DIR/data" -m fast -w stop >/dev/null || true
rm -rf "$DIR"
