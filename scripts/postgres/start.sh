#!/usr/bin/env bash
# Starts a throwaway PostgreSQL for the test suite: a new cluster in DIR (default a new
# temporary directory), listening on 127.0.0.1:PORT (default 55432) and its own socket
# directory, with a role and database `tessera` (password `tessera`, required over TCP);
# LISTEN (default 127.0.0.1) is the address it listens on (scripts/testfarm: a namespace's).
# Prints the URL to use as TESSERA_TEST_POSTGRES. Needs Debian's `postgresql` package
# (installed here when missing and we are root). Stop it with scripts/postgres/stop.sh DIR.
# Usage: start.sh [DIR [PORT [LISTEN]]]
set -euo pipefail
DIR="${1:-$(mktemp -d /tmp/tessera-pg.XXXXXX)}"
PORT="${2:-55432}"
LISTEN="${3:-127.0.0.1}"

bin=""
for d in /usr/lib/postgresql/*/bin; do [ -x "$d/initdb" ] && bin="$d"; done
if [ -z "$bin" ]; then
  if [ "$(id -u)" = 0 ]; then
    apt-get update -qq >&2
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq postgresql >/dev/null
  else
    echo "PostgreSQL is not installed (apt-get install postgresql)" >&2
    exit 1
  fi
  for d in /usr/lib/postgresql/*/bin; do [ -x "$d/initdb" ] && bin="$d"; done
fi

# PostgreSQL refuses to run as root: as root, the cluster belongs to the `postgres` user.
as=()
if [ "$(id -u)" = 0 ]; then
  id postgres >/dev/null 2>&1 || useradd --system --no-create-home postgres
  chown postgres "$DIR"
  as=(runuser -u postgres --)
fi
mkdir -p "$DIR/data"
chown --reference="$DIR" "$DIR/data"
"${as[@]}" "$bin/initdb" -D "$DIR/data" -U postgres --auth-local=trust --auth-host=scram-sha-256 \
  -E UTF8 >"$DIR/initdb.log"
cat >>"$DIR/data/postgresql.conf" <<CONF
listen_addresses = '$LISTEN'
port = $PORT
unix_socket_directories = '$DIR'
max_connections = 300
fsync = off
CONF
# Clients on the listening address's own subnet too (the namespaces of scripts/testfarm).
echo "host all all samenet scram-sha-256" >>"$DIR/data/pg_hba.conf"
"${as[@]}" "$bin/pg_ctl" -D "$DIR/data" -l "$DIR/server.log" -w start >/dev/null
"${as[@]}" "$bin/psql" -h "$DIR" -p "$PORT" -U postgres -q -v ON_ERROR_STOP=1 \
  -c "CREATE ROLE tessera LOGIN PASSWORD 'tessera'" -c "CREATE DATABASE tessera OWNER tessera" >&2
echo "postgres://tessera:tessera@$LISTEN:$PORT/tessera"
