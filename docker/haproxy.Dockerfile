# HAProxy 2.6 from Debian 12's own package, tagged haproxy:2.6 where no registry is reachable:
#   podman build -f docker/haproxy.Dockerfile -t docker.io/library/haproxy:2.6 docker
# It runs like the official image as docker/compose.yaml uses it: the configuration at
# /usr/local/etc/haproxy/haproxy.cfg, as user haproxy, in the foreground (-db) with the
# master-worker mode (-W) that reloads on SIGUSR2. SIGUSR1 is a soft stop: finish, then exit.
FROM debian:12
RUN apt-get update \
 && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends haproxy \
 && rm -rf /var/lib/apt/lists/* \
 && mkdir -p /usr/local/etc/haproxy \
 && haproxy -v | grep -q "version 2\.6\."
USER haproxy
STOPSIGNAL SIGUSR1
CMD ["haproxy", "-W", "-db", "-f", "/usr/local/etc/haproxy/haproxy.cfg"]
