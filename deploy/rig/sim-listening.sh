#!/bin/bash
# ecat-sim's health check: a packet socket is bound to sim0 (column 5 of /proc/net/packet
# is the interface index), i.e. the simulated segment answers frames.
ifindex=$(cat /sys/class/net/sim0/ifindex) || exit 1
awk -v ifindex="$ifindex" 'NR > 1 && $5 == ifindex { found = 1 } END { exit !found }' /proc/net/packet
