#!/bin/bash
# The rig's EtherCAT link (compose service ecat-link): a veth pair in this container's
# network namespace, which ecatd (ecat0) and ecat-sim (sim0) join. Then waits until the
# container is stopped; the pair goes with the namespace.
set -euo pipefail
if [ ! -e /sys/class/net/ecat0 ]; then
  ip link add ecat0 type veth peer name sim0
fi
# No IP on either end: only EtherCAT frames (and nothing the kernel would send on its own)
# cross the pair.
for end in ecat0 sim0; do
  sysctl -qw "net.ipv6.conf.$end.disable_ipv6=1" 2>/dev/null || true
  ip link set "$end" up
done
echo "ecat-link: ecat0 <-> sim0 up"
trap 'exit 0' TERM INT
sleep infinity &
wait
