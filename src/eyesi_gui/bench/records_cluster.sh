#!/usr/bin/env bash
# A throw-away PostgreSQL cluster for bench_records (issue 41): `records_cluster.sh start DIR` initialises and starts
# one in DIR (created; owned by the unprivileged user that runs it: postgres, or nobody, since initdb and postgres
# refuse to run as root), listening on a Unix socket in DIR only (no TCP port), trust for local connections (a bench
# cluster, never a centre's), and prints the libpq connection string of its `records` database;
# `records_cluster.sh stop DIR` stops it and removes DIR.
set -euo pipefail
command=${1:-}
dir=${2:-}
[[ -n $command && -n $dir ]] || { echo "usage: records_cluster.sh start|stop DIR" >&2; exit 2; }
bin=$(ls -d /usr/lib/postgresql/*/bin | sort -V | tail -n 1)
user=postgres
id -u "$user" >/dev/null 2>&1 || user=nobody
as_user() {
  if [[ $(id -u) -eq 0 ]]; then runuser -u "$user" -- "$@"; else "$@"; fi
}
case $command in
  start)
    mkdir -p "$dir"
    [[ $(id -u) -eq 0 ]] && chown "$user" "$dir"
    as_user "$bin/initdb" -D "$dir/data" -U postgres -E UTF8 --auth-local=trust --auth-host=reject >"$dir/initdb.log"
    as_user "$bin/pg_ctl" -D "$dir/data" -l "$dir/postgres.log" -w -t 60 \
      -o "-c listen_addresses='' -c unix_socket_directories='$dir' -c port=5432 -c shared_buffers=256MB" start >/dev/null
    as_user "$bin/createdb" -h "$dir" -p 5432 -U postgres records
    echo "host=$dir port=5432 dbname=records user=postgres"
    ;;
  stop)
    if [[ -f $dir/data/postmaster.pid ]]; then
      as_user "$bin/pg_ctl" -D "$dir/data" -m fast stop >/dev/null || true
    fi
    rm -rf "$dir"
    ;;
  *)
    echo "usage: records_cluster.sh start|stop DIR" >&2
    exit 2
    ;;
esac
