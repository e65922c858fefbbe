#!/usr/bin/env bash
# The container image really built and run (README "Deployment"): builds docker/Dockerfile with
# podman, runs the image and checks it from outside as a user would, then runs docker/compose.yaml
# with podman-compose and the failover scenario of tests/deploy/failover_test.cpp against the two
# containerised replicas behind the containerised HAProxy.
#   tests/deploy/container_test.sh --client MTLOD-CLIENT --load MTLOD-LOAD --gen MTLOD-GEN
# ctest runs it with the build tree's programs (tests/CMakeLists.txt). No registry is contacted:
#   - the Debian 12 base is made by debootstrap from the mirror apt uses and imported as
#     docker.io/library/debian:12, trusting the host's extra CA certificates (npm goes through them);
#   - haproxy:2.6 is built from Debian's haproxy package (docker/haproxy.Dockerfile).
# Images and podman's layer cache are kept between runs (and ccache's objects in a build cache
# mount), so a rerun rebuilds only what changed; containers, the network and scratch files are
# removed on exit. Exit 77 (a skip) only where podman cannot run containers at all.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)

client="" load="" gen=""
while (($#)); do
  case "$1" in
    --client) client=$2; shift 2 ;;
    --load) load=$2; shift 2 ;;
    --gen) gen=$2; shift 2 ;;
    *) echo "usage: $0 --client MTLOD-CLIENT --load MTLOD-LOAD --gen MTLOD-GEN" >&2; exit 2 ;;
  esac
done
for program in "$client" "$load" "$gen"; do
  [ -x "$program" ] || { echo "container_test: not an executable: '$program'" >&2; exit 2; }
done

started=$SECONDS
say() { printf '[%4ds] %s\n' "$((SECONDS - started))" "$*"; }
skip() { echo "SKIP: $*"; exit 77; }
work=""
fail() {
  echo "FAIL: $*" >&2
  [ -z "$work" ] || echo "logs kept in $work" >&2
  exit 1
}

# ---- Can podman run containers here at all? ----
[ "$(id -u)" -eq 0 ] || skip "needs root: the test runs rootful podman and debootstrap"
command -v podman >/dev/null || skip "podman is not installed (scripts/bootstrap.sh installs it)"
# runc needs these namespaces for every container; a sandbox without them cannot run any.
unshare --mount --uts --ipc --net --pid --fork true 2>/dev/null \
  || skip "this kernel or sandbox refuses new namespaces, so podman cannot run containers"
podman info >/dev/null 2>&1 || skip "podman cannot run here: $(podman info 2>&1 | tail -n 1)"
for tool in debootstrap podman-compose draco_decoder curl python3 flock nsenter; do
  command -v "$tool" >/dev/null || fail "$tool is missing (scripts/bootstrap.sh installs it)"
done

# One run at a time per machine: runs share the image tags, the layer cache and the base image.
exec 9>/var/tmp/mtlod-container-test.lock
flock 9

work=$(mktemp -d "${TMPDIR:-/tmp}/mtlod-container.XXXXXX")
# The replicas run as uid 10001 and read the models mounted from here.
chmod 755 "$work"
project="mtlodtest$$"
single="$project-single" drain="$project-drain"
compose=(podman-compose -p "$project" -f "$root/docker/compose.yaml")

rootfs=""  # debootstrap's folder while the base is being made
# podman-compose needs the variables compose.yaml reads even to take the project down.
export MTLOD_MODELS="$work/models" MTLOD_PUBLISH_ADDRESS=127.0.0.1
cleanup() {
  local status=$? name pid
  # A client or load run of a failed check may still be going.
  for pid in $(jobs -p); do kill "$pid" 2>/dev/null || true; done
  if [ "$status" -ne 0 ]; then
    # The containers' own logs go with the others before the containers do.
    for name in $(podman ps -a --format '{{.Names}}' 2>/dev/null | grep "^$project" || true); do
      podman logs "$name" >"$work/container-$name.log" 2>&1 || true
    done
  fi
  podman rm --force --ignore --time 0 "$single" "$drain" >/dev/null 2>&1 || true
  [ -z "$rootfs" ] || rm -rf "$rootfs"
  if [ -f "$work/compose-up.log" ]; then
    "${compose[@]}" down >"$work/compose-down.log" 2>&1 || true
    podman network rm --force "${project}_default" >/dev/null 2>&1 || true
  fi
  # Logs stay for a failed run (fail() names the folder).
  if [ "$status" -eq 0 ]; then rm -rf "$work"; fi
}
trap cleanup EXIT

# ---- containers.conf for this test only (CONTAINERS_CONF, not the machine's own) ----
# runc, not crun: crun 1.8 refuses this kernel's hybrid cgroup hierarchy ("cgroups in hybrid mode
# not supported, drop all controllers from cgroupv2"). Ulimits: root here lacks CAP_SYS_RESOURCE,
# so runc cannot give a container a hard limit above its own (EPERM "error setting rlimits"), and
# podman's default nofile and nproc (1048576) are above the host's. containers/common also sets
# podman's own RLIMIT_NPROC to kernel.pid_max as it reads its configuration (lowering it here), so
# nproc may be no higher than that either.
nofile=$(ulimit -Hn) nproc=$(ulimit -Hu)
pid_max=$(cat /proc/sys/kernel/pid_max)
[ "$nofile" != unlimited ] || nofile=1048576
if [ "$nproc" = unlimited ] || [ "$nproc" -gt "$pid_max" ]; then nproc=$pid_max; fi
cat >"$work/containers.conf" <<EOF
[containers]
default_ulimits = ["nofile=$nofile:$nofile", "nproc=$nproc:$nproc"]
[engine]
runtime = "runc"
EOF
export CONTAINERS_CONF="$work/containers.conf"

# ---- The Debian 12 base ----
# Made here when missing, or when the host's extra CA certificates changed since it was made (the
# base must trust them: npm ci reaches the registry through them). A debian:12 this test did not
# make (pulled from a registry) is used as it is.
ca_dir=/usr/local/share/ca-certificates
ca_digest=$( (find "$ca_dir" -type f -name '*.crt' -print0 2>/dev/null | sort -z | xargs -0r cat) | sha256sum | cut -c1-16)
base=docker.io/library/debian:12
base_digest=""
if podman image exists "$base"; then
  base_digest=$(podman image inspect --format '{{index .Config.Labels "io.mtlod.ca-digest"}}' "$base")
  [ "$base_digest" != "<no value>" ] || base_digest=""
fi
if ! podman image exists "$base" || { [ -n "$base_digest" ] && [ "$base_digest" != "$ca_digest" ]; }; then
  # The mirrors apt uses here for bookworm and its security updates (Debian's own otherwise);
  # $(REPO_URI) is apt's field name, not a shell expansion.
  # shellcheck disable=SC2016
  mirror=$(apt-get indextargets --format '$(REPO_URI)' 'Codename: bookworm' 'Created-By: Packages' 2>/dev/null | head -n 1)
  # shellcheck disable=SC2016
  security=$(apt-get indextargets --format '$(REPO_URI)' 'Codename: bookworm-security' 'Created-By: Packages' 2>/dev/null | head -n 1)
  mirror=${mirror:-http://deb.debian.org/debian/} security=${security:-http://deb.debian.org/debian-security/}
  say "making $base with debootstrap from $mirror"
  rootfs=$(mktemp -d /var/tmp/mtlod-debootstrap.XXXXXX)
  if ! nice -n 10 debootstrap --variant=minbase bookworm "$rootfs" "$mirror" >"$work/debootstrap.log" 2>&1; then
    tail -n 20 "$work/debootstrap.log" >&2
    fail "debootstrap bookworm from $mirror failed"
  fi
  # The sources of Debian's own debian:12 image (bookworm, its updates, security) on these mirrors.
  rm -f "$rootfs/etc/apt/sources.list"
  cat >"$rootfs/etc/apt/sources.list.d/debian.sources" <<EOF
Types: deb
URIs: $mirror
Suites: bookworm bookworm-updates
Components: main
Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg

Types: deb
URIs: $security
Suites: bookworm-security
Components: main
Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg
EOF
  # update-ca-certificates adds these when a build installs ca-certificates.
  mkdir -p "$rootfs$ca_dir"
  find "$ca_dir" -type f -name '*.crt' -exec cp {} "$rootfs$ca_dir/" \; 2>/dev/null || true
  rm -rf "$rootfs"/var/cache/apt/archives/*.deb "$rootfs"/var/lib/apt/lists/*
  tar -C "$rootfs" -c . | podman import --change 'CMD ["bash"]' \
    --change "LABEL io.mtlod.ca-digest=$ca_digest" - "$base" >"$work/import.log" 2>&1 \
    || fail "podman import of the debootstrap base failed: $(tail -n 3 "$work/import.log")"
  rm -rf "$rootfs"
  rootfs=""
fi
podman run --rm --network none "$base" true 2>"$work/probe.log" \
  || fail "podman cannot start a container from $base: $(tail -n 3 "$work/probe.log")"
say "base image $base ready"

# ---- The images ----
# build_image LOG TAG DOCKERFILE CONTEXT: nice'd, layers reused, Docker format (keeps HEALTHCHECK).
# Each log line is stamped with the epoch second, so the steps that took long can be named.
build_image() {
  local log=$1 tag=$2 file=$3 context=$4 begin=$SECONDS
  if ! nice -n 10 podman build --network host --format docker --layers -f "$file" -t "$tag" "$context" 2>&1 \
    | while IFS= read -r line; do printf '%(%s)T %s\n' -1 "$line"; done >"$log"; then
    tail -n 40 "$log" >&2
    fail "podman build -f $file failed"
  fi
  say "built $tag in $((SECONDS - begin)) s"
  # Steps of 10 s or more, each timed up to the next step's first line (or the last line).
  awk 'function report(end) { if (step != "" && end - start >= 10) printf "  %4d s  %.90s\n", end - start, step }
       ($2 ~ /^\[[0-9]+\/[0-9]+\]$/ && $3 == "STEP") || $2 == "STEP" { report($1); step = substr($0, length($1) + 2); start = $1 }
       { last = $1 }
       END { report(last) }' "$log"
}
previous=$(podman image inspect --format '{{.Id}}' localhost/mtlod:latest 2>/dev/null || true)
build_image "$work/build-mtlod.log" localhost/mtlod:latest "$root/docker/Dockerfile" "$root"
# ccache's counts for the compile step (the log's lines start with their time stamp).
sed -n -E 's/^[0-9]+ +(Hits|Misses): */  ccache \1: /p' "$work/build-mtlod.log"
current=$(podman image inspect --format '{{.Id}}' localhost/mtlod:latest)
# The image this build replaced has no tag left and its layers no further use (one that a
# container still uses stays).
if [ -n "$previous" ] && [ "$previous" != "$current" ]; then podman image rm "$previous" >/dev/null 2>&1 || true; fi
# The build stage's layers are kept as untagged images. Tagged, the current ones stay, so pruning
# by the stage's label removes only those that earlier builds left behind (a changed
# scripts/bootstrap.sh strands 1.6 GB of apt and npm layers).
nice -n 10 podman build --network host --format docker --layers --target build -f "$root/docker/Dockerfile" \
  -t localhost/mtlod:build-stage "$root" >"$work/build-stage.log" 2>&1 \
  || fail "tagging the build stage failed: $(tail -n 5 "$work/build-stage.log")"
podman image prune --force --filter label=io.mtlod.stage=build >"$work/prune.log" 2>&1 \
  || fail "podman image prune failed: $(tail -n 3 "$work/prune.log")"
build_image "$work/build-haproxy.log" docker.io/library/haproxy:2.6 "$root/docker/haproxy.Dockerfile" "$root/docker"

[ "$(podman image inspect --format '{{.Config.User}}' mtlod)" = mtlod ] || fail "the image does not run as user mtlod"

# ---- Helpers ----
http_port() { podman port "$1" "$2" | head -n 1 | sed 's/.*://'; }
# Waits until GET http://127.0.0.1:PORT/health answers 200, up to 30 s.
wait_healthy() {
  local port=$1 name=$2
  for _ in $(seq 150); do
    curl -fsS "http://127.0.0.1:$port/health" >/dev/null 2>&1 && return 0
    sleep 0.2
  done
  podman logs "$name" >&2 || true
  fail "$name: /health never answered on port $port"
}
# The value of one Prometheus sample (exact name and labels) in a /metrics text.
metric() { awk -v name="$2" '$1 == name { print $2; found = 1 } END { if (!found) print "missing" }' "$1"; }
# Little-endian uint32 as printf %b escapes: the frame header of PROTOCOL.md "Framing".
le32() { printf '%08x' "$1" | sed -E 's/(..)(..)(..)(..)/\\x\4\\x\3\\x\2\\x\1/'; }
# The faces a PLY header declares.
ply_faces() { head -c 4096 "$1" | tr -d '\r' | awk '$1 == "element" && $2 == "face" { print $3; exit }'; }

# ---- The image as shipped: the protocol, /health, /metrics, HEALTHCHECK, SIGTERM ----
podman run -d --name "$single" -p 127.0.0.1::7878 -p 127.0.0.1::8080 mtlod >"$work/single-run.log" 2>&1 \
  || fail "podman run mtlod: $(tail -n 3 "$work/single-run.log")"
port=$(http_port "$single" 7878) hport=$(http_port "$single" 8080)
wait_healthy "$hport" "$single"
curl -fsS "http://127.0.0.1:$hport/health" >"$work/health.json"
say "container $single: protocol on 127.0.0.1:$port, HTTP on 127.0.0.1:$hport"

# hello by hand, frame by frame (independent of the clients' code): the reply names the protocol
# version and the instance that /health names.
hello='{"type":"hello","id":1,"version":1,"client":"container_test"}'
exec 3<>"/dev/tcp/127.0.0.1/$port" || fail "cannot connect to 127.0.0.1:$port"
printf '%b%s' "$(le32 ${#hello})$(le32 0)" "$hello" >&3
# od reads the two uint32 in host order: little-endian, as the frame (x86-64 and arm64 alike).
read -r json_bytes payload_bytes < <(timeout 10 dd bs=1 count=8 <&3 2>/dev/null | od -An -tu4)
if [ -z "${json_bytes:-}" ] || [ "${payload_bytes:-}" != 0 ]; then
  fail "hello: no reply, or a frame header with a payload (${json_bytes:-?} + ${payload_bytes:-?} bytes)"
fi
timeout 10 dd bs=1 count="$json_bytes" <&3 2>/dev/null >"$work/hello.json"
exec 3<&-
python3 - "$work/hello.json" "$work/health.json" <<'EOF' || fail "hello or /health is wrong"
import json, re, sys
hello, health = (json.load(open(p)) for p in sys.argv[1:3])
problems = []
if (hello.get("type"), hello.get("id"), hello.get("version")) != ("hello", 1, 1):
    problems.append(f"hello reply {hello}")
if health.get("status") != "ok" or health.get("models") != 1:
    problems.append(f"/health {health}: want status ok and the one baked-in model")
if not re.fullmatch(r".+@[0-9a-f]{8}", hello.get("instance", "")) or hello.get("instance") != health.get("instance"):
    problems.append(f"hello instance {hello.get('instance')!r} is not /health's {health.get('instance')!r}")
for p in problems: print("  " + p, file=sys.stderr)
sys.exit(1 if problems else 0)
EOF
say "ok: hello by hand (protocol 1, instance $(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["instance"])' "$work/hello.json")) and /health agree"

# The image's own HEALTHCHECK (a protocol round trip as user mtlod); podman runs it on demand
# here since its timers need systemd.
podman healthcheck run "$single" >"$work/healthcheck.log" 2>&1 || fail "HEALTHCHECK failed: $(cat "$work/healthcheck.log")"
[ "$(podman exec "$single" id -u)" = 10001 ] || fail "the server does not run as uid 10001"
say "ok: HEALTHCHECK passes, the server runs as uid 10001"

# An extract of the baked-in bunny at error 0 is the whole mesh: the Stanford bunny of npm `bunny`
# has 3,674 triangles (scripts/prepare-models.sh), and Google's draco_decoder must read them all
# from the payload.
"$client" --port "$port" --attempts 1 extract bunny --error 0 -o "$work/bunny.drc" >"$work/bunny.log" 2>&1 \
  || fail "mtlod-client extract bunny: $(cat "$work/bunny.log")"
draco_decoder -i "$work/bunny.drc" -o "$work/bunny.ply" >"$work/bunny-decode.log" 2>&1 \
  || fail "draco_decoder cannot decode the extract's payload: $(cat "$work/bunny-decode.log")"
[ "$(ply_faces "$work/bunny.ply")" = 3674 ] || fail "draco_decoder read $(ply_faces "$work/bunny.ply") triangles, want 3674"
grep -q "^bunny: 3674 triangles" "$work/bunny.log" || fail "the reply does not say 3674 triangles: $(cat "$work/bunny.log")"
say "ok: extract bunny --error 0: 3674 triangles, decoded by draco_decoder"

curl -fsS -D "$work/metrics.head" "http://127.0.0.1:$hport/metrics" >"$work/metrics.txt" || fail "GET /metrics failed"
grep -qi '^content-type: text/plain; version=0.0.4' "$work/metrics.head" || fail "/metrics: not Prometheus text: $(cat "$work/metrics.head")"
[ "$(metric "$work/metrics.txt" 'mtlod_requests_total{type="extract"}')" = 1 ] \
  || fail "/metrics counts $(metric "$work/metrics.txt" 'mtlod_requests_total{type="extract"}') extracts, want 1"
[ "$(metric "$work/metrics.txt" mtlod_sent_triangles_total)" = 3674 ] \
  || fail "/metrics counts $(metric "$work/metrics.txt" mtlod_sent_triangles_total) triangles sent, want 3674"
say "ok: /metrics counts the one extract and its 3674 triangles"

# SIGTERM with nothing in flight: exit 0 at once, long before the 20 s drain bound.
begin=$SECONDS
podman stop --time 30 "$single" >/dev/null 2>&1 || fail "podman stop $single failed"
code=$(podman inspect --format '{{.State.ExitCode}}' "$single")
[ "$code" = 0 ] || fail "$single exited $code on SIGTERM, want 0"
((SECONDS - begin <= 5)) || fail "$single took $((SECONDS - begin)) s to stop with nothing to drain"
say "ok: podman stop (SIGTERM): exit 0 in $((SECONDS - begin)) s"

# ---- A model large enough for an extraction to be in flight when SIGTERM comes ----
"$gen" --shape sphere --triangles 1000000 -o "$work/sphere.ply" >"$work/gen.log" 2>&1 \
  || fail "mtlod-gen: $(cat "$work/gen.log")"
sphere_triangles=$(ply_faces "$work/sphere.ply")
mkdir -p "$work/models"
# The image's own mtlod-build (an optimised build) writes it, as the invoking user.
podman run --rm --user "$(id -u):$(id -g)" -v "$work:/work" --entrypoint mtlod-build mtlod \
  /work/sphere.ply -o /work/models/sphere.mt >"$work/build-model.log" 2>&1 \
  || fail "mtlod-build in the image: $(tail -n 5 "$work/build-model.log")"
chmod 755 "$work/models" && chmod 644 "$work/models/sphere.mt"
say "sphere.mt: $sphere_triangles triangles, built by the image's mtlod-build"

# ---- SIGTERM drain with an extraction in flight (the image's --drain-timeout-ms 20000) ----
podman run -d --name "$drain" -p 127.0.0.1::7878 -p 127.0.0.1::8080 -v "$work/models:/models:ro" mtlod \
  >"$work/drain-run.log" 2>&1 || fail "podman run (drain): $(tail -n 3 "$work/drain-run.log")"
port=$(http_port "$drain" 7878) hport=$(http_port "$drain" 8080)
wait_healthy "$hport" "$drain"
# The whole sphere (error 0) takes about 2 s to refine and encode here.
"$client" --port "$port" --attempts 1 extract sphere --error 0 -o "$work/sphere.drc" >"$work/sphere.log" 2>&1 &
client_pid=$!
# In flight: the request has parsed and no extraction has finished.
in_flight=0
for _ in $(seq 300); do
  curl -fsS "http://127.0.0.1:$hport/metrics" >"$work/drain-metrics.txt" 2>/dev/null || true
  if [ "$(metric "$work/drain-metrics.txt" 'mtlod_requests_total{type="extract"}')" = 1 ]; then
    in_flight=1
    break
  fi
  sleep 0.02
done
[ "$in_flight" = 1 ] || fail "the extract never reached the server: $(cat "$work/sphere.log")"
[ "$(metric "$work/drain-metrics.txt" 'mtlod_extraction_duration_seconds_count{type="extract",stage="total"}')" = 0 ] \
  || fail "the extraction finished before SIGTERM: the drain was not tested (a larger model is needed)"
begin=$SECONDS
podman stop --time 40 "$drain" >/dev/null 2>&1 || fail "podman stop $drain failed"
stopped_s=$((SECONDS - begin))
code=$(podman inspect --format '{{.State.ExitCode}}' "$drain")
[ "$code" = 0 ] || fail "$drain exited $code on SIGTERM with work in flight, want 0 (137: podman had to SIGKILL it)"
((stopped_s <= 22)) || fail "$drain took $stopped_s s to drain, over its 20 s bound"
wait "$client_pid" || fail "the extraction in flight was cut off by the drain: $(cat "$work/sphere.log")"
# The server's log shows the order: the drain began, then the extraction finished.
podman logs "$drain" >"$work/drain.log" 2>/dev/null
awk '/shutting down/ && !drain { drain = NR } /extract model=sphere/ && !done { done = NR }
     END { exit !(drain && done && drain < done) }' "$work/drain.log" \
  || fail "$drain's log does not show the extraction finishing after the drain began: $(tail -n 5 "$work/drain.log")"
draco_decoder -i "$work/sphere.drc" -o "$work/sphere-decoded.ply" >"$work/sphere-decode.log" 2>&1 \
  || fail "draco_decoder cannot decode the drained extract: $(cat "$work/sphere-decode.log")"
[ "$(ply_faces "$work/sphere-decoded.ply")" = "$sphere_triangles" ] \
  || fail "the drained extract has $(ply_faces "$work/sphere-decoded.ply") triangles, want all $sphere_triangles"
say "ok: SIGTERM during an extraction: its reply arrived whole ($sphere_triangles triangles), exit 0 in $stopped_s s"

# ---- docker/compose.yaml: two replicas behind HAProxy, one killed under load ----
free_port() { python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }
MTLOD_PUBLISH_PORT=$(free_port) MTLOD_PUBLISH_HTTP_PORT=$(free_port) MTLOD_PUBLISH_STATS_PORT=$(free_port)
export MTLOD_PUBLISH_PORT MTLOD_PUBLISH_HTTP_PORT MTLOD_PUBLISH_STATS_PORT
"${compose[@]}" up -d >"$work/compose-up.log" 2>&1 || { cat "$work/compose-up.log" >&2; fail "podman-compose up failed"; }
replica1="${project}_mtlod-1_1"
stats="http://127.0.0.1:$MTLOD_PUBLISH_STATS_PORT/stats;csv"
# Field 18 of HAProxy's CSV is the status, 5 the current sessions.
backend_field() { curl -fsS "$stats" 2>/dev/null | awk -F, -v server="$1" -v field="$2" '$1 == "replicas" && $2 == server { print $field }'; }
wait_until_up() {
  local server=$1
  for _ in $(seq 300); do
    [ "$(backend_field "$server" 18)" = UP ] && return 0
    sleep 0.2
  done
  podman logs "${project}_haproxy_1" >&2 || true
  fail "HAProxy never saw $server up"
}
wait_until_up replica-1
wait_until_up replica-2
say "compose: HAProxy on 127.0.0.1:$MTLOD_PUBLISH_PORT sees both replicas up"
# Each start of a replica logs its instance (NAME@8 hex digits) as it starts listening.
instance_of() { podman logs "$1" 2>/dev/null | sed -n 's/.* \(mtlod-[12]@[0-9a-f]*\) listening.*/\1/p' | tail -n 1; }
first_instance=$(instance_of "$replica1")
[ -n "$first_instance" ] || fail "$replica1 logged no instance"

# As tests/deploy/failover_test.cpp: a closed loop through HAProxy, connections recycled every 10
# requests so the balancer can place them on the restarted replica.
"$load" --port "$MTLOD_PUBLISH_PORT" --model sphere --connections 4 --duration 14 --budget 2000 \
  --reconnect-after 10 --attempts 40 --quiet --json "$work/load.json" >"$work/load.log" 2>&1 &
load_pid=$!
sleep 3
kill -0 "$load_pid" 2>/dev/null || fail "mtlod-load ended early: $(cat "$work/load.log")"
for _ in $(seq 50); do
  sessions=$(backend_field replica-1 5)
  [ "${sessions:-0}" -ge 1 ] && break
  sleep 0.2
done
[ "${sessions:-0}" -ge 1 ] || fail "no load connection reached replica-1"
# Killed as a crash or the OOM killer would (SIGKILL to the server, PID 1 of the container):
# `podman kill` would count as a deliberate stop, after which restart: unless-stopped rightly
# leaves the container down.
kill -KILL "$(podman inspect --format '{{.State.Pid}}' "$replica1")"
say "killed $first_instance (SIGKILL) with $sessions load connection(s) on it"
restarted=""
for _ in $(seq 150); do
  restarted=$(instance_of "$replica1")
  [ -n "$restarted" ] && [ "$restarted" != "$first_instance" ] && break
  sleep 0.2
done
if [ -z "$restarted" ] || [ "$restarted" = "$first_instance" ]; then
  fail "compose's restart policy did not bring $replica1 back"
fi
wait_until_up replica-1
say "restart policy: $replica1 is back as $restarted"

wait "$load_pid" || fail "mtlod-load failed: $(cat "$work/load.log")"
# Nothing lost: the criteria of failover_test.cpp.
python3 - "$work/load.json" "$first_instance" "$restarted" <<'EOF' || { cat "$work/load.log" >&2; fail "the load report shows requests lost or unbalanced"; }
import json, sys
r = json.load(open(sys.argv[1]))
first, restarted = sys.argv[2], sys.argv[3]
instances = r.get("instances", {})
checks = [
    (r["sent"] > 0, "requests were sent"),
    (r["ok"] == r["sent"], f"every request answered (ok {r['ok']}, sent {r['sent']})"),
    (r["errors"] == 0, f"no error replies ({r['errors']})"),
    (r["lost"] == 0, f"none lost ({r['lost']})"),
    (r["unsent"] == 0, f"none unsent ({r['unsent']})"),
    (r["gave_up"] == 0, f"no stream gave up ({r['gave_up']})"),
    (r["retried"] >= 1, f"the kill caught requests in flight, which were sent again ({r['retried']})"),
    (r["reconnects"] >= 1, f"reconnects ({r['reconnects']})"),
    (first in instances, f"{first} served before the kill"),
    (restarted in instances and instances[restarted]["ok"] > 0, f"{restarted} served after its restart"),
    (any(name.startswith("mtlod-2@") for name in instances), "mtlod-2 served"),
    (sum(i["ok"] for i in instances.values()) == r["ok"], "every reply is counted on one instance"),
]
if first in instances and restarted in instances:
    checks.append((instances[restarted]["first_reply_s"] > instances[first]["last_reply_s"],
                   "the restarted replica answered after the killed one stopped"))
failed = [text for good, text in checks if not good]
for text in failed: print("  not true: " + text, file=sys.stderr)
print(f"  load report: sent {r['sent']}, ok {r['ok']}, lost {r['lost']}, retried {r['retried']}, "
      f"reconnects {r['reconnects']}; by instance " +
      ", ".join(f"{k} {v['ok']}" for k, v in sorted(instances.items())))
sys.exit(1 if failed else 0)
EOF
# Counted on both sides: each replica that lived to the end says on its /metrics that it wrote
# exactly the meshes the client counted from its instance (the killed one's counters died with it).
# The replicas publish no port; their /metrics is read from inside their network namespace, over
# loopback, which sends no PROXY header. A write is counted a moment after the client holds its bytes.
served_by() {
  local pid
  pid=$(podman inspect --format '{{.State.Pid}}' "$1")
  nsenter --target "$pid" --net curl -fsS http://127.0.0.1:8080/metrics 2>/dev/null | awk '$1 == "mtlod_sent_meshes_total" { print $2 }'
}
received_from() { python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["instances"][sys.argv[2]]["ok"])' "$work/load.json" "$1"; }
replica2="${project}_mtlod-2_1"
for container in "$replica1" "$replica2"; do
  instance=$(instance_of "$container")
  received=$(received_from "$instance") || fail "the load report has no replies from $instance"
  served=""
  for _ in $(seq 20); do
    served=$(served_by "$container" || true)
    [ "$served" = "$received" ] && break
    sleep 0.1
  done
  [ "$served" = "$received" ] || fail "$instance says it sent ${served:-no} meshes; the client received $received from it"
  say "ok: $instance sent $served meshes, the client received $received from it"
done
say "ok: failover through the containerised HAProxy: every request answered, none lost"
echo "container_test: all checks passed in $((SECONDS - started)) s"
