#!/usr/bin/env bash
# A throwaway PostgreSQL server for the history tests, from Debian's package (installed where it is
# missing): a cluster in a temporary data directory, listening on 127.0.0.1 only, TLS on with a
# self-signed certificate and every TCP login required to use it (hostssl, scram-sha-256 password).
#
#   eval "$(tools/test_postgres.sh start)"   start one; prints the environment the tests read:
#                                             DRIVE_BRIDGE_TEST_POSTGRES (URL without password; the role
#                                             may create databases),
#                                             DRIVE_BRIDGE_TEST_POSTGRES_PASSWORD, .._DIR
#   tools/test_postgres.sh stop DIR          stop it (the data stay)
#   tools/test_postgres.sh restart DIR       start it again, same port
#   tools/test_postgres.sh remove DIR        stop it and delete DIR
set -euo pipefail
bindir() { ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V | tail -1; }
as_postgres() { if [ "$(id -u)" -eq 0 ]; then runuser -u postgres -- "$@"; else "$@"; fi; }
pg_ctl_() { local dir=$1; shift; as_postgres "$(bindir)/pg_ctl" -D "$dir/data" -l "$dir/server.log" "$@" >/dev/null; }
case "${1:-}" in
start)
    if [ -z "$(bindir)" ]; then
        sudo=""; [ "$(id -u)" -ne 0 ] && sudo="sudo -n"
        export DEBIAN_FRONTEND=noninteractive
        { $sudo apt-get install -y -q postgresql >/dev/null 2>&1 ||
          { $sudo apt-get update -q >/dev/null 2>&1 && $sudo apt-get install -y -q postgresql >/dev/null 2>&1; }; } ||
            { echo "test_postgres: Debian's postgresql package could not be installed" >&2; exit 1; }
    fi
    dir=$(mktemp -d /tmp/drive-bridge-pg.XXXXXX)
    password=$(head -c 24 /dev/urandom | base64 | tr -dc 'A-Za-z0-9' | head -c 24)
    port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
    [ "$(id -u)" -eq 0 ] && chown postgres: "$dir"
    as_postgres "$(bindir)/initdb" -D "$dir/data" -U postgres --auth-local=trust --auth-host=reject \
        -E UTF8 --locale=C.UTF-8 >/dev/null
    as_postgres openssl req -x509 -newkey rsa:2048 -nodes -days 2 -subj /CN=localhost \
        -keyout "$dir/data/server.key" -out "$dir/data/server.crt" 2>/dev/null
    as_postgres chmod 600 "$dir/data/server.key"
    printf 'local all all trust\nhostssl all all 127.0.0.1/32 scram-sha-256\n' | as_postgres tee "$dir/data/pg_hba.conf" >/dev/null
    printf "listen_addresses = '127.0.0.1'\nport = %s\nunix_socket_directories = '%s'\nssl = on\nfsync = off\n" \
        "$port" "$dir" | as_postgres tee -a "$dir/data/postgresql.conf" >/dev/null
    pg_ctl_ "$dir" -w start
    as_postgres psql -q -h "$dir" -p "$port" -U postgres -d postgres \
        -c "CREATE ROLE drivebridge LOGIN CREATEDB PASSWORD '$password'" -c "CREATE DATABASE drivebridge OWNER drivebridge" >/dev/null
    echo "export DRIVE_BRIDGE_TEST_POSTGRES='postgresql://drivebridge@127.0.0.1:$port/drivebridge'"
    echo "export DRIVE_BRIDGE_TEST_POSTGRES_PASSWORD='$password'"
    echo "export DRIVE_BRIDGE_TEST_POSTGRES_DIR='$dir'"
    ;;
stop) pg_ctl_ "$2" -m fast -w stop ;;
restart) pg_ctl_ "$2" -w start ;;
remove) pg_ctl_ "$2" -m immediate -w stop 2>/dev/null || true; rm -rf "$2" ;;
*) echo "usage: $0 start | stop DIR | restart DIR | remove DIR" >&2; exit 2 ;;
esac
