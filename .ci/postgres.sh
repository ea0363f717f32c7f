# Sourced by .ci/run: a throw-away PostgreSQL server on loopback for the tests that share one Optuna study between
# processes on a real RDB server. Uses THERMODRIFT_TEST_POSTGRES (a SQLAlchemy URL) when it is already set;
# otherwise installs Debian's postgresql when it is missing (as root), starts a server, exports the URL and stops
# the server, by its own PID, when the calling shell exits. Sets THERMODRIFT_REQUIRE_POSTGRES=1 whenever a server
# is there, so those tests fail rather than skip.
pg_bin() { ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V | tail -n 1; }
if [ -z "${THERMODRIFT_TEST_POSTGRES:-}" ]; then
    if [ -z "$(pg_bin)" ] && [ "$(id -u)" -eq 0 ]; then
        apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq postgresql >/dev/null
    fi
    if [ -z "$(pg_bin)" ]; then
        echo "PostgreSQL is not installed and this user cannot install it: its tests will be skipped" >&2
    else
        PG_BIN="$(pg_bin)"
        PG_DIR="$(mktemp -d /tmp/thermodrift-pg.XXXXXX)"
        PG_PORT="${THERMODRIFT_PG_PORT:-55432}"
        # PostgreSQL refuses to run as root; setpriv execs in place, so $! below is the server's own PID.
        PG_AS=()
        if [ "$(id -u)" -eq 0 ]; then
            chown postgres "$PG_DIR"
            PG_AS=(setpriv --reuid=postgres --regid=postgres --init-groups --)
        fi
        "${PG_AS[@]}" "$PG_BIN/initdb" -D "$PG_DIR/data" -A trust -U postgres >/dev/null
        "${PG_AS[@]}" "$PG_BIN/postgres" -D "$PG_DIR/data" -k "$PG_DIR" -c listen_addresses=127.0.0.1 \
            -p "$PG_PORT" >"$PG_DIR/server.log" 2>&1 &
        PG_PID=$!
        trap 'kill "$PG_PID" 2>/dev/null; wait "$PG_PID" 2>/dev/null; rm -rf "$PG_DIR"' EXIT
        for _ in $(seq 60); do
            "$PG_BIN/pg_isready" -q -h 127.0.0.1 -p "$PG_PORT" && break
            sleep 0.5
        done
        "$PG_BIN/pg_isready" -q -h 127.0.0.1 -p "$PG_PORT" || { cat "$PG_DIR/server.log" >&2; exit 1; }
        export THERMODRIFT_TEST_POSTGRES="postgresql+psycopg2://postgres@127.0.0.1:$PG_PORT/postgres"
    fi
fi
if [ -n "${THERMODRIFT_TEST_POSTGRES:-}" ]; then
    export THERMODRIFT_REQUIRE_POSTGRES=1
fi
