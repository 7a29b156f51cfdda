#!/usr/bin/env bash
# Two "hosts" on one machine for latency runs: network namespaces joined by a veth pair, with
# netem delay, jitter and loss on both ends (so the round trip sees twice DELAY_MS).
#
#   sudo deploy/netem/two-hosts.sh up       # create (or update the netem settings of) the pair
#   sudo deploy/netem/two-hosts.sh status   # show namespaces, addresses and qdiscs
#   sudo deploy/netem/two-hosts.sh down     # remove everything it created
#
# Settings, from the environment or flags (flags win):
#   DELAY_MS   / --delay-ms MS     one-way delay on each end, ms       (default 10)
#   JITTER_MS  / --jitter-ms MS    jitter around the delay, ms          (default 0)
#   LOSS_PCT   / --loss-pct PCT    random loss on each end, percent     (default 0)
#   NETEM_PREFIX / --prefix P      name prefix: namespaces P-server and P-ws, veth P-s and P-w
#                                  (default hs; give each concurrent user its own, <= 12 chars)
#   SUBNET     / --subnet A.B.C    the /24 used: server A.B.C.1, workstation A.B.C.2
#                                  (default 10.77.0; each pair lives in its own namespaces, so
#                                  concurrent pairs may share it)
#
# Then, e.g.:
#   sudo ip netns exec hs-server haptics-server --listen 10.77.0.1:7700 ...
#   sudo ip netns exec hs-ws workstation latency --server 10.77.0.1:7700 ...
#
# Exit codes: 0 done; 1 a command failed; 2 bad usage or settings; 3 not root or ip/tc missing;
# 4 (status only) the pair is not up; 5 the kernel has no netem qdisc (CONFIG_NET_SCH_NETEM).
# `up` is idempotent (rerun it to change the netem settings) and a failed `up` removes what it
# made; with delay, jitter and loss all 0 it adds no qdisc, so it works without netem.
# `down` succeeds when nothing is left, whether or not anything was there.
set -euo pipefail

usage() {
  sed -n '2,/^set -euo/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//' >&2
  exit 2
}

die() {
  local code=$1
  shift
  echo "two-hosts: $*" >&2
  exit "$code"
}

DELAY_MS=${DELAY_MS:-10}
JITTER_MS=${JITTER_MS:-0}
LOSS_PCT=${LOSS_PCT:-0}
NETEM_PREFIX=${NETEM_PREFIX:-hs}
SUBNET=${SUBNET:-10.77.0}

(($# >= 1)) || usage
action=$1
shift
while (($#)); do
  case $1 in
    --delay-ms) DELAY_MS=${2:?--delay-ms needs a value}; shift 2 ;;
    --jitter-ms) JITTER_MS=${2:?--jitter-ms needs a value}; shift 2 ;;
    --loss-pct) LOSS_PCT=${2:?--loss-pct needs a value}; shift 2 ;;
    --prefix) NETEM_PREFIX=${2:?--prefix needs a value}; shift 2 ;;
    --subnet) SUBNET=${2:?--subnet needs a value}; shift 2 ;;
    -h | --help) usage ;;
    *) die 2 "unknown argument: $1 (try --help)" ;;
  esac
done

number='^[0-9]+([.][0-9]+)?$'
[[ $DELAY_MS =~ $number ]] || die 2 "DELAY_MS must be a non-negative number (got '$DELAY_MS')"
[[ $JITTER_MS =~ $number ]] || die 2 "JITTER_MS must be a non-negative number (got '$JITTER_MS')"
[[ $LOSS_PCT =~ $number ]] || die 2 "LOSS_PCT must be a non-negative number (got '$LOSS_PCT')"
awk -v l="$LOSS_PCT" 'BEGIN { exit !(l <= 100) }' || die 2 "LOSS_PCT must be at most 100 (got $LOSS_PCT)"
# Interface names are limited to 15 characters: "<prefix>-s" must fit.
[[ $NETEM_PREFIX =~ ^[A-Za-z0-9_]{1,12}$ ]] ||
  die 2 "NETEM_PREFIX must be 1-12 letters, digits or _ (got '$NETEM_PREFIX')"
[[ $SUBNET =~ ^[0-9]{1,3}[.][0-9]{1,3}[.][0-9]{1,3}$ ]] ||
  die 2 "SUBNET must look like 10.77.0 (got '$SUBNET')"

NS_SERVER="$NETEM_PREFIX-server"
NS_WS="$NETEM_PREFIX-ws"
VETH_SERVER="$NETEM_PREFIX-s"
VETH_WS="$NETEM_PREFIX-w"
ADDR_SERVER="$SUBNET.1"
ADDR_WS="$SUBNET.2"

need_tools() {
  [ "$(id -u)" -eq 0 ] || die 3 "needs root (network namespaces and qdiscs): run it with sudo"
  command -v ip >/dev/null || die 3 "'ip' not found: install iproute2"
  command -v tc >/dev/null || die 3 "'tc' not found: install iproute2"
}

ns_exists() {
  ip netns list | awk '{print $1}' | grep -qx -- "$1"
}

netem_args() {
  local args=(delay "${DELAY_MS}ms")
  if [ "$JITTER_MS" != 0 ]; then
    args+=("${JITTER_MS}ms" distribution normal)
  fi
  if [ "$LOSS_PCT" != 0 ]; then
    args+=(loss "${LOSS_PCT}%")
  fi
  echo "${args[@]}"
}

no_impairment() {
  awk -v d="$DELAY_MS" -v j="$JITTER_MS" -v l="$LOSS_PCT" 'BEGIN { exit !(d == 0 && j == 0 && l == 0) }'
}

up() {
  need_tools
  for ns in "$NS_SERVER" "$NS_WS"; do
    ns_exists "$ns" || ip netns add "$ns"
    ip -n "$ns" link set lo up
  done
  if ! ip -n "$NS_SERVER" link show "$VETH_SERVER" >/dev/null 2>&1; then
    # A half-made pair from an interrupted run: start that end again.
    ip -n "$NS_WS" link del "$VETH_WS" >/dev/null 2>&1 || true
    ip link del "$VETH_SERVER" >/dev/null 2>&1 || true
    ip link add "$VETH_SERVER" netns "$NS_SERVER" type veth peer name "$VETH_WS" netns "$NS_WS"
  fi
  ip -n "$NS_SERVER" addr replace "$ADDR_SERVER/24" dev "$VETH_SERVER"
  ip -n "$NS_WS" addr replace "$ADDR_WS/24" dev "$VETH_WS"
  ip -n "$NS_SERVER" link set "$VETH_SERVER" up
  ip -n "$NS_WS" link set "$VETH_WS" up
  local shaping
  if no_impairment; then
    # Nothing to emulate: no qdisc, so this works on kernels without netem too.
    for end in "$NS_SERVER:$VETH_SERVER" "$NS_WS:$VETH_WS"; do
      if ip netns exec "${end%%:*}" tc qdisc show dev "${end#*:}" | grep -q netem; then
        ip netns exec "${end%%:*}" tc qdisc del dev "${end#*:}" root
      fi
    done
    shaping="no netem (delay, jitter and loss all 0)"
  else
    for end in "$NS_SERVER:$VETH_SERVER" "$NS_WS:$VETH_WS"; do
      local err
      # shellcheck disable=SC2046 # netem_args is a list of words on purpose
      if ! err=$(ip netns exec "${end%%:*}" tc qdisc replace dev "${end#*:}" root netem $(netem_args) 2>&1); then
        down >/dev/null
        if [[ $err == *"qdisc kind is unknown"* ]]; then
          die 5 "this kernel has no netem qdisc (CONFIG_NET_SCH_NETEM; try 'modprobe sch_netem'); removed what was set up"
        fi
        die 1 "tc qdisc replace ... netem $(netem_args) failed: $err; removed what was set up"
      fi
    done
    shaping="netem $(netem_args) on each end (round trip ≈ $(awk -v d="$DELAY_MS" 'BEGIN { print 2 * d }') ms)"
  fi
  echo "two-hosts: up: $NS_SERVER ($ADDR_SERVER, $VETH_SERVER) <-> $NS_WS ($ADDR_WS, $VETH_WS); $shaping"
  echo "  server:      ip netns exec $NS_SERVER haptics-server --listen $ADDR_SERVER:7700 ..."
  echo "  workstation: ip netns exec $NS_WS workstation ... --server $ADDR_SERVER:7700"
}

down() {
  need_tools
  local removed=()
  for ns in "$NS_SERVER" "$NS_WS"; do
    if ns_exists "$ns"; then
      # Deleting a namespace destroys the veth end in it, and with it the peer.
      ip netns del "$ns"
      removed+=("$ns")
    fi
  done
  # A veth end left in the root namespace by an interrupted `up`.
  for dev in "$VETH_SERVER" "$VETH_WS"; do
    if ip link show "$dev" >/dev/null 2>&1; then
      ip link del "$dev"
      removed+=("$dev")
    fi
  done
  if ((${#removed[@]})); then
    echo "two-hosts: down: removed ${removed[*]}"
  else
    echo "two-hosts: down: nothing to remove (prefix $NETEM_PREFIX)"
  fi
}

status() {
  need_tools
  local ok=0
  for ns in "$NS_SERVER" "$NS_WS"; do
    if ns_exists "$ns"; then
      echo "== $ns"
      ip -n "$ns" -brief addr show
      ip netns exec "$ns" tc qdisc show | grep netem || echo "(no netem qdisc)"
    else
      echo "== $ns: absent"
      ok=4
    fi
  done
  return "$ok"
}

case $action in
  up) up ;;
  down) down ;;
  status) status ;;
  -h | --help | help) usage ;;
  *) die 2 "unknown action '$action': up, down or status" ;;
esac
