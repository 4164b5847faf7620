"""A real ROS 2 Jazzy peer (rclpy + Fast DDS) for the fleet tests.

Run inside a private network namespace (the Rust test does it). It starts the fleet, acts as
a ROS user would (`ros2 topic pub`, `ros2 param get/set`, kill a node, Ctrl-C the launcher)
and prints what it saw as one JSON object on stdout. The assertions are the Rust test's.

    python fleet_peer.py walk|ik|ik_on_receive|teleop|watchdog|bridge_ticks|launch|sim|sim_delay BIN_DIR [PARAMS_YAML]
"""

import json
import math
import os
import signal
import subprocess
import sys
import time

import rclpy
import rclpy.executors
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rcl_interfaces.msg import Log, Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import GetParameters, SetParameters
from geometry_msgs.msg import Twist
from sensor_msgs.msg import JointState
from biped_msgs.msg import AnkleTargets, GaitPhase, WalkCommand

NODES = ["gait_planner", "ik_solver", "joint_bridge"]
# Every process a scenario starts (nodes, launchers): whatever still runs when the scenario
# ends, even by an exception, is stopped, so a failed scenario leaves no fleet behind to
# load the machine for the next test.
STARTED = []


def stamp_ns(header):
    return header.stamp.sec * 1_000_000_000 + header.stamp.nanosec


class Peer:
    def __init__(self):
        rclpy.init()
        self.node = rclpy.create_node("test_peer")
        qos = QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE)
        self.phases, self.commands, self.states, self.rosout = [], [], [], []
        self.t0 = time.monotonic()
        n = self.node
        n.create_subscription(GaitPhase, "/gait/phase", lambda m: self.phases.append(
            {"stamp": stamp_ns(m.header), "phase": m.phase, "support": m.support, "step": m.step_index}), qos)
        n.create_subscription(JointState, "/joint_commands", lambda m: self.commands.append(
            {"stamp": stamp_ns(m.header), "name": list(m.name), "position": list(m.position)}), qos)
        # "t": the bridge's own stamp (system clock, s), so a slow peer cannot blur the timing.
        n.create_subscription(JointState, "/joint_states", lambda m: self.states.append(
            {"t": stamp_ns(m.header) * 1e-9, "name": list(m.name), "position": list(m.position)}), qos)
        n.create_subscription(Log, "/rosout", lambda m: self.rosout.append(
            {"t": self.now(), "stamp": m.stamp.sec * 1_000_000_000 + m.stamp.nanosec, "name": m.name,
             "level": int(m.level), "msg": m.msg}), QoSProfile(depth=1000))
        self.walk_pub = n.create_publisher(WalkCommand, "/walk_command", 10)
        self.cmd_vel_pub = n.create_publisher(Twist, "/cmd_vel", 10)

    def now(self):
        return time.monotonic() - self.t0

    def spin(self, seconds, until=None):
        end = time.monotonic() + seconds
        next_check = 0.0
        while time.monotonic() < end:
            rclpy.spin_once(self.node, timeout_sec=0.005)
            # The condition (a graph query, a scan of what arrived) at most every 20 ms, so
            # that a busy stream does not starve the spinning.
            if until is not None and time.monotonic() >= next_check:
                next_check = time.monotonic() + 0.02
                if until():
                    return True
        return False

    def node_names(self):
        return sorted(name for name, _ in self.node.get_node_names_and_namespaces())

    def wait_for_nodes(self, timeout=20.0):
        """Until rclpy's graph lists every fleet node. A running rclpy used to miss one of our
        nodes now and then (Fast DDS lost our `ros_discovery_info` writer's announcement:
        fixed in patches/rustdds, "source timestamps"), and a restarted observer listed it.
        As a last resort, after half the time a fresh observer (a new rclpy context: a new
        DDS participant) looks too, as a user would run `ros2 node list` again, and says so
        on stderr. Every node must still be seen by one of the two."""
        if self.spin(timeout / 2, lambda: all(x in self.node_names() for x in NODES)):
            return True
        ctx = rclpy.Context()
        ctx.init()
        probe = rclpy.create_node("test_peer_probe", context=ctx)
        executor = rclpy.executors.SingleThreadedExecutor(context=ctx)
        executor.add_node(probe)
        try:
            end = time.monotonic() + timeout / 2
            while time.monotonic() < end:
                executor.spin_once(timeout_sec=0.02)
                rclpy.spin_once(self.node, timeout_sec=0.005)
                names = {name for name, _ in probe.get_node_names_and_namespaces()}
                if all(x in names for x in NODES):
                    self.fresh_observer_needed = True
                    print("wait_for_nodes: only a fresh observer saw every node", file=sys.stderr)
                    return True
            return False
        finally:
            executor.shutdown()
            probe.destroy_node()
            ctx.shutdown()

    def wait_for_subscribers(self, publisher, timeout=10.0):
        # Never sleep and hope: wait until the fleet's subscription has matched.
        return self.spin(timeout, lambda: publisher.get_subscription_count() > 0)

    def call(self, srv_type, name, request, timeout=30.0):
        # One client per service, kept: a new client's endpoints must be discovered by the
        # server again (seconds with RustDDS), which would delay the call by that much.
        clients = self.__dict__.setdefault("clients", {})
        client = clients.get(name)
        if client is None:
            client = clients[name] = self.node.create_client(srv_type, name)
        if not client.wait_for_service(timeout_sec=timeout):
            return None
        future = client.call_async(request)
        self.spin(timeout, lambda: future.done())
        return future.result()

    def get_param(self, node, name):
        r = self.call(GetParameters, f"/{node}/get_parameters", GetParameters.Request(names=[name]))
        if r is None or not r.values:
            return None
        v = r.values[0]
        return {"type": int(v.type), "double": v.double_value, "string": v.string_value,
                "bool": v.bool_value, "integer": v.integer_value}

    def set_double(self, node, name, value):
        p = Parameter(name=name, value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value))
        r = self.call(SetParameters, f"/{node}/set_parameters", SetParameters.Request(parameters=[p]))
        if r is None:
            return None
        return {"successful": bool(r.results[0].successful), "reason": r.results[0].reason}

    def walk(self, steps, step_length=0.0, step_duration=0.0, stop=False):
        self.walk_pub.publish(WalkCommand(steps=steps, step_length=step_length, step_duration=step_duration, stop=stop))

    def wait_for_flow(self, timeout=30.0):
        """Until the idle fleet's pipeline is connected end to end: joint commands and joint
        states arriving (discovery between the nodes can take seconds on a loaded machine)."""
        ok = self.spin(timeout, lambda: len(self.commands) > 5 and len(self.states) > 5)
        if not ok:
            self.flow_diag = {
                "commands": len(self.commands), "states": len(self.states), "phases": len(self.phases),
                "nodes": self.node_names(),
                "publishers": {t: self.node.count_publishers(t) for t in ("/joint_commands", "/joint_states", "/gait/phase", "/gait/ankle_targets")},
                "t": self.now()}
            print("FLOW DIAG", json.dumps(self.flow_diag), file=sys.stderr)
        return ok

    def idle_after_walking(self):
        walked = [p for p in self.phases if p["phase"] != "idle"]
        return bool(walked) and self.phases[-1]["phase"] == "idle"


def start_nodes(bin_dir, params, extra=None, only=None, env=None):
    """Starts the fleet's nodes (`only` some), `extra` arguments and `env` variables per
    node name, and waits until each has logged "ready:"."""
    procs = {}
    for name in only or NODES:
        args = [os.path.join(bin_dir, name), "--ros-args"]
        if params:
            args += ["--params-file", params]
        args += (extra or {}).get(name, [])
        node_env = dict(os.environ, **(env or {}).get(name, {}))
        procs[name] = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                                       env=node_env)
        STARTED.append(procs[name])
    # The peer's participant comes after the nodes' ones, as the scenarios mean it to (a peer
    # started together with the nodes is tests/cold_start.rs's case).
    not_ready = wait_until_ready(procs)
    if not_ready:
        print(f"not ready after 30 s: {sorted(not_ready)}", file=sys.stderr)
    return procs


def wait_until_ready(procs, timeout=30.0):
    """Until every node has logged "ready" (its DDS participant is up) or exited; returns the
    names still starting. What they logged until then is kept in `p.early_stderr` for
    stop_nodes. Reads the pipes' file descriptors, as `communicate` does later, so that no
    text waits in a Python buffer in between."""
    import selectors
    sel = selectors.DefaultSelector()
    for name, p in procs.items():
        p.early_stderr = ""
        sel.register(p.stderr.fileno(), selectors.EVENT_READ, (name, p))
    waiting = set(procs)
    end = time.monotonic() + timeout
    while waiting and time.monotonic() < end:
        for key, _ in sel.select(timeout=0.1):
            name, p = key.data
            chunk = os.read(key.fd, 65536).decode(errors="replace")
            p.early_stderr += chunk
            if "ready:" in p.early_stderr or not chunk:
                waiting.discard(name)
                sel.unregister(key.fd)
    sel.close()
    return waiting


def stop_nodes(procs):
    errors = {}
    for name, p in procs.items():
        if p.poll() is None:
            p.send_signal(signal.SIGINT)
    for name, p in procs.items():
        try:
            _, err = p.communicate(timeout=10)
        except subprocess.TimeoutExpired:
            p.kill()
            _, err = p.communicate()
        err = getattr(p, "early_stderr", "") + (err or "")
        errors[name] = {"returncode": p.returncode, "stderr_tail": err[-2000:]}
    return errors


def record_markers(peer):
    """Every gait/markers array, decoded by rclpy: per array its stamp and, by namespace,
    what each marker draws."""
    from visualization_msgs.msg import MarkerArray
    got = []

    def on(m):
        entry = {"stamp": stamp_ns(m.markers[0].header) if m.markers else None,
                 "frame": m.markers[0].header.frame_id if m.markers else None}
        for k in m.markers:
            entry.setdefault(k.ns, []).append({
                "id": k.id, "type": k.type, "action": k.action,
                "xyz": [k.pose.position.x, k.pose.position.y, k.pose.position.z],
                "scale": [k.scale.x, k.scale.y, k.scale.z],
                "points": [[p.x, p.y] for p in k.points], "text": k.text})
        got.append(entry)

    peer.node.create_subscription(MarkerArray, "/gait/markers", on,
                                  QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE))
    return got


def scenario_walk(bin_dir, params):
    procs = start_nodes(bin_dir, params)
    peer = Peer()
    markers = record_markers(peer)
    out = {"nodes_seen": peer.wait_for_nodes()}
    out["node_names"] = peer.node_names()
    out["param_before"] = peer.get_param("gait_planner", "step_duration_s")
    out["matched"] = peer.wait_for_subscribers(peer.walk_pub) and peer.wait_for_subscribers(peer.cmd_vel_pub)
    out["flowing"] = peer.wait_for_flow()
    out["flow_diag"] = getattr(peer, "flow_diag", None)
    peer.walk(2)
    # Bad commands during the walk: each must be refused with a warning, the walk unaffected.
    peer.spin(2.5)
    bad = Twist()
    bad.linear.x = math.nan
    peer.cmd_vel_pub.publish(bad)
    turn = Twist()
    turn.linear.x = 0.01
    turn.angular.z = 0.5
    peer.cmd_vel_pub.publish(turn)
    # A walk command that cannot be read (a CDR header and two bytes of its first field, sent
    # as a serialized message): dropped with a warning naming the topic.
    peer.walk_pub.publish(b"\x00\x01\x00\x00\x03\x00")
    peer.walk(3, step_length=-1.0)
    peer.walk(3, step_duration=math.inf)
    # A step length the walk in progress cannot take (parameters change between walks).
    peer.walk(3, step_length=0.03)
    out["set_during_walk"] = peer.set_double("gait_planner", "step_duration_s", 0.8)
    out["finished"] = peer.spin(40.0, peer.idle_after_walking)
    peer.spin(0.5)
    out["set_after_walk"] = peer.set_double("gait_planner", "foot_lift_m", 0.02)
    out["set_invalid"] = peer.set_double("gait_planner", "control_rate_hz", 5000.0)
    out["param_after"] = peer.get_param("gait_planner", "foot_lift_m")
    # Swings left at 0 (auto): the node searches the fastest timing, and the next walk (one
    # step) swings that long.
    out["set_auto"] = peer.set_double("gait_planner", "step_duration_s", 0.0)
    peer.spin(0.5)

    def walked_from(n):
        later = [p["phase"] for p in peer.phases[n:]]
        return any(ph != "idle" for ph in later) and later[-1] == "idle"

    def one_step(name, step_length=0.0):
        """A one-step walk, recorded as `{name}_walk_finished` and `{name}_walk_from`."""
        n = len(peer.phases)
        peer.walk(1, step_length=step_length)
        out[f"{name}_walk_finished"] = peer.spin(30.0, lambda: walked_from(n))
        out[f"{name}_walk_from"] = n
        peer.spin(0.3)

    one_step("auto")
    # A walk command with a new step length, durations auto: its timing search runs off the
    # control loop, which goes on ticking meanwhile; then the walk.
    one_step("searched", step_length=0.05)
    # Durations set again, then a walk command with a new step length: on the monotonic
    # clock its check walks run off the control loop too, which goes on ticking; then the walk.
    out["set_timed"] = peer.set_double("gait_planner", "step_duration_s", 1.0)
    peer.spin(0.5)
    one_step("checked", step_length=0.04)
    # And one without: the configured step length again, not the last command's.
    one_step("configured")
    out.update(phases=peer.phases, commands=peer.commands, rosout=peer.rosout,
               states_count=len(peer.states), states_last=peer.states[-1] if peer.states else None,
               markers=markers)
    out["exits"] = stop_nodes(procs)
    return out


def scenario_ik(bin_dir, params, on_receive=False):
    """The ik_solver alone, fed by the peer: warm-up targets until its joint commands come
    back, then 300 targets at about 100 Hz (stamps 10 s + k ns), the 150th with a NaN left
    ankle x. `on_receive`: the node solves on its DDS thread (`solve_on_receive`, its
    default), or on its own thread; given either way."""
    extra = {"ik_solver": ["-p", f"solve_on_receive:={'true' if on_receive else 'false'}"]}
    procs = start_nodes(bin_dir, params, extra=extra, only=["ik_solver"])
    peer = Peer()
    pub = peer.node.create_publisher(AnkleTargets, "/gait/ankle_targets",
                                     QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
    out = {"matched": peer.wait_for_subscribers(pub)}

    def targets(sec, k, nan=False):
        m = AnkleTargets()
        m.header.stamp.sec, m.header.stamp.nanosec = sec, k
        m.header.frame_id = "base_link"
        s = math.sin(k * 0.05)
        m.left_ankle.x, m.left_ankle.y, m.left_ankle.z = 0.02 * s, 0.01 * s, -0.14 - 0.01 * s
        m.right_ankle.x, m.right_ankle.y, m.right_ankle.z = -0.02 * s, -0.01 * s, -0.14 + 0.01 * s
        m.left_foot_yaw, m.right_foot_yaw = 0.1 * s, -0.1 * s
        if nan:
            m.left_ankle.x = math.nan
        return m

    # Until a command comes back: the node's writer has matched our reader too.
    warm = 0
    while not peer.commands and warm < 400:
        pub.publish(targets(1, warm))
        warm += 1
        peer.spin(0.05)
    out["warm_up"] = warm
    peer.spin(0.2)
    peer.commands.clear()
    sent = []
    for k in range(300):
        m = targets(10, k, nan=(k == 150))
        pub.publish(m)
        sent.append([k, m.left_ankle.x, m.left_ankle.y, m.left_ankle.z, m.left_foot_yaw,
                     m.right_ankle.x, m.right_ankle.y, m.right_ankle.z, m.right_foot_yaw])
        peer.spin(0.01)
    peer.spin(10.0, lambda: len(peer.commands) >= 299 and any(
        "ankle targets refused" in r["msg"] for r in peer.rosout))
    peer.spin(0.3)
    out.update(sent=[[None if isinstance(x, float) and math.isnan(x) else x for x in row] for row in sent],
               commands=peer.commands, rosout=peer.rosout)
    out["exits"] = stop_nodes(procs)
    return out


def scenario_teleop(bin_dir, params):
    """A teleop: Twists at 10 Hz to side-step left, then the teleop dies (no more Twists):
    the walk must end by itself (cmd_vel_timeout_s) with the feet together."""
    procs = start_nodes(bin_dir, params)
    peer = Peer()
    pelvis = []
    peer.node.create_subscription(AnkleTargets, "/gait/ankle_targets", lambda m: pelvis.append(
        {"stamp": stamp_ns(m.header), "x": m.pelvis.x, "y": m.pelvis.y}),
        QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE))
    from nav_msgs.msg import Odometry
    odom = []
    peer.node.create_subscription(Odometry, "/odom", lambda m: odom.append(
        {"stamp": stamp_ns(m.header), "frame": m.header.frame_id, "child": m.child_frame_id,
         "x": m.pose.pose.position.x, "y": m.pose.pose.position.y, "qz": m.pose.pose.orientation.z,
         "qw": m.pose.pose.orientation.w, "cov": list(m.pose.covariance), "vy": m.twist.twist.linear.y}),
        QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE))
    out = {"nodes_seen": peer.wait_for_nodes(), "matched": peer.wait_for_subscribers(peer.cmd_vel_pub)}
    out["flowing"] = peer.wait_for_flow()
    out["flow_diag"] = getattr(peer, "flow_diag", None)
    side = Twist()
    side.linear.y = 0.004
    end = time.monotonic() + 14.0
    while time.monotonic() < end:
        peer.cmd_vel_pub.publish(side)
        peer.spin(0.1)
    out["finished"] = peer.spin(40.0, peer.idle_after_walking)
    peer.spin(0.5)
    out.update(phases=peer.phases, pelvis=pelvis, rosout=peer.rosout, odom_count=len(odom),
               odom_first=odom[0] if odom else None, odom_last=odom[-1] if odom else None,
               odom_max_vy=max((o["vy"] for o in odom), default=None))
    out["exits"] = stop_nodes(procs)
    return out


def start_flowing(bin_dir, params, extra=None):
    """Starts the nodes and a peer, and waits for commands and states to flow; if they never
    do, the nodes are stopped already (out["flowing"] false)."""
    procs = start_nodes(bin_dir, params, extra)
    peer = Peer()
    out = {"nodes_seen": peer.wait_for_nodes(), "matched": peer.wait_for_subscribers(peer.walk_pub)}
    out["flowing"] = peer.wait_for_flow()
    out["flow_diag"] = getattr(peer, "flow_diag", None)
    if not out["flowing"]:
        out["exits"] = stop_nodes(procs)
        print(json.dumps(out["exits"]), file=sys.stderr)
    return procs, peer, out


def scenario_bridge_ticks(bin_dir, params):
    """The joint_bridge alone (mock backend) at 1 Hz, fed by the peer: 14 joint commands
    0.6 s apart. Records when each was sent (system clock, s) and the stamp of every
    joint_states (the bridge's tick, the same clock). With `tick_on_command` (the default)
    each command ticks the bridge as it comes; on its 1 Hz ticks alone a command would find a
    tick within 0.6 s only 60 % of the time."""
    extra = {"joint_bridge": ["-p", "backend:=mock", "-p", "rate_hz:=1.0", "-p", "watchdog_timeout_s:=5.0"]}
    procs = start_nodes(bin_dir, params, extra=extra, only=["joint_bridge"])
    peer = Peer()
    pub = peer.node.create_publisher(JointState, "/joint_commands",
                                     QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE))
    out = {"matched": peer.wait_for_subscribers(pub)}
    # Its joint_states reach us (its writer matched our reader): the joint names.
    out["flowing"] = peer.spin(20.0, lambda: len(peer.states) >= 2)
    if not out["flowing"]:
        out["exits"] = stop_nodes(procs)
        return out
    names = peer.states[-1]["name"]
    sent = []
    for k in range(14):
        m = JointState()
        m.name = names
        m.position = [0.001 * (k + 1)] * len(names)
        sent.append(time.time())
        m.header.stamp.sec, m.header.stamp.nanosec = int(sent[-1]), int((sent[-1] % 1) * 1e9)
        pub.publish(m)
        peer.spin(0.6)
    peer.spin(0.5)
    out.update(sent=sent, states=[x["t"] for x in peer.states], rosout=peer.rosout)
    out["exits"] = stop_nodes(procs)
    return out


def scenario_sim_delay(bin_dir, params):
    """The sim_bridge alone, in lockstep and as fast as answered, the peer its joint bridge:
    it answers every /clock t with a sim/joint_commands stamped t, every joint at 0 rad
    (where the robot stands from the start) but l_elbow, which steps to -0.3 rad from
    t = 1 s on. Three simulators one after another, with command_delay_s 0, 0.01 and 0.005;
    records l_elbow's measured position by the stamp of each joint_states (ns)."""
    from rosgraph_msgs.msg import Clock
    peer = Peer()
    n = peer.node
    qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    pub = n.create_publisher(JointState, "/sim/joint_commands", qos)
    step_at_ns = 1_000_000_000
    clock = []

    def answer(m):
        t_ns = m.clock.sec * 1_000_000_000 + m.clock.nanosec
        clock.append(t_ns)
        if not peer.states:
            return  # the simulator says t again in 50 ms
        c = JointState()
        c.header.stamp = m.clock
        c.name = peer.states[-1]["name"]
        c.position = [-0.3 if (j == "l_elbow" and t_ns >= step_at_ns) else 0.0 for j in c.name]
        pub.publish(c)

    n.create_subscription(Clock, "/clock", answer, qos)
    out = {"runs": {}, "exits": {}, "ready": {}}
    for delay in ["0.0", "0.01", "0.005"]:
        extra = {"sim_bridge": ["-p", "real_time_factor:=0.0", "-p", f"command_delay_s:={delay}"]}
        procs = start_nodes(bin_dir, params, extra=extra, only=["sim_bridge"])
        peer.states.clear()
        clock.clear()
        done = peer.spin(60.0, lambda: bool(clock) and clock[-1] >= step_at_ns + 300_000_000)
        ready = [ln for ln in procs["sim_bridge"].early_stderr.splitlines() if "ready:" in ln]
        out["ready"][delay] = ready[-1] if ready else None
        elbow = {}
        for st in peer.states:
            if "l_elbow" in st["name"]:
                elbow[str(round(st["t"] * 1e9))] = st["position"][st["name"].index("l_elbow")]
        out["runs"][delay] = {"done": done, "elbow": elbow}
        out["exits"][delay] = stop_nodes(procs)["sim_bridge"]
        peer.spin(0.5)
    return out


def scenario_watchdog(bin_dir, params):
    extra = {"joint_bridge": ["-p", "watchdog_timeout_s:=0.2"]}
    procs, peer, out = start_flowing(bin_dir, params, extra)
    if not out["flowing"]:
        return out
    peer.walk(0)  # until stopped
    # Into the walk (crouch 1 s, then the 2 s shift): wait until the joints move, then a bit.
    first = peer.states[-1]["position"]
    out["moving"] = peer.spin(30.0, lambda: peer.states[-1]["position"] != first)
    peer.spin(1.5)
    procs["ik_solver"].kill()
    procs["ik_solver"].wait()
    out["kill_t"] = time.time()  # the clock of the joint_states stamps
    peer.spin(2.0)
    out.update(states=peer.states, rosout=peer.rosout)
    out["exits"] = stop_nodes(procs)
    return out


def scenario_estop(bin_dir, params):
    """Mid-walk, an operator calls ~/estop on the joint bridge (std_srvs/Trigger, as `ros2
    service call /joint_bridge/estop std_srvs/srv/Trigger` does); later ~/reset, then
    ~/set_torque false and true (std_srvs/SetBool). Records every answer and joint_states."""
    from std_srvs.srv import SetBool, Trigger
    procs, peer, out = start_flowing(bin_dir, params)
    if not out["flowing"]:
        return out

    def answer(r):
        return None if r is None else {"success": bool(r.success), "message": r.message}

    # A reset with nothing to reset is refused, saying so.
    out["early_reset"] = answer(peer.call(Trigger, "/joint_bridge/reset", Trigger.Request()))
    # A walk scheduled 1.5 s ahead, then a stop: the stop cancels it, nothing walks.
    from builtin_interfaces.msg import Time
    start = time.time() + 1.5
    peer.walk_pub.publish(WalkCommand(steps=2, start_time=Time(sec=int(start), nanosec=int((start % 1) * 1e9))))
    peer.spin(0.3)
    peer.walk(0, stop=True)
    cancel_from = len(peer.phases)
    peer.spin(3.0)
    out["phases_after_cancel"] = sorted({p["phase"] for p in peer.phases[cancel_from:]})
    peer.walk(0)  # until stopped
    first = peer.states[-1]["position"]
    out["moving"] = peer.spin(30.0, lambda: peer.states[-1]["position"] != first)
    peer.spin(1.5)
    out["estop_t"] = time.time()  # the clock of the joint_states stamps
    out["estop"] = answer(peer.call(Trigger, "/joint_bridge/estop", Trigger.Request()))
    out["estop_answered_t"] = time.time()
    peer.spin(2.0)
    out["reset_t"] = time.time()
    out["reset"] = answer(peer.call(Trigger, "/joint_bridge/reset", Trigger.Request()))
    out["reset_answered_t"] = time.time()
    peer.spin(1.5)
    out["torque_t"] = time.time()
    out["torque_off"] = answer(peer.call(SetBool, "/joint_bridge/set_torque", SetBool.Request(data=False)))
    out["torque_on"] = answer(peer.call(SetBool, "/joint_bridge/set_torque", SetBool.Request(data=True)))
    peer.spin(0.5)
    out.update(states=peer.states, rosout=peer.rosout)
    out["exits"] = stop_nodes(procs)
    return out


def scenario_pause(bin_dir, params):
    """Mid-walk, an operator calls ~/pause on the gait planner (std_srvs/SetBool, as `ros2
    service call /gait_planner/pause std_srvs/srv/SetBool "{data: true}"` does), twice; later
    false, twice. Records every answer, the joint commands and the phases."""
    from std_srvs.srv import SetBool
    procs, peer, out = start_flowing(bin_dir, params)
    if not out["flowing"]:
        return out

    def answer(r):
        return None if r is None else {"success": bool(r.success), "message": r.message}

    peer.walk(0)  # until stopped
    first = peer.commands[-1]["position"]
    out["moving"] = peer.spin(30.0, lambda: peer.commands[-1]["position"] != first)
    peer.spin(1.5)
    out["pause_t"] = time.time()  # the clock of the command stamps
    out["pause"] = answer(peer.call(SetBool, "/gait_planner/pause", SetBool.Request(data=True)))
    out["pause_answered_t"] = time.time()
    out["pause_again"] = answer(peer.call(SetBool, "/gait_planner/pause", SetBool.Request(data=True)))
    peer.spin(2.0)
    out["resume_t"] = time.time()
    out["resume"] = answer(peer.call(SetBool, "/gait_planner/pause", SetBool.Request(data=False)))
    out["resume_again"] = answer(peer.call(SetBool, "/gait_planner/pause", SetBool.Request(data=False)))
    peer.spin(2.0)
    peer.walk(0, stop=True)
    peer.spin(0.5)
    out.update(commands=peer.commands, phases=peer.phases, rosout=peer.rosout)
    out["exits"] = stop_nodes(procs)
    return out


def scenario_lifecycle(bin_dir, params):
    """The joint bridge as a managed node, driven as `ros2 lifecycle` drives one: mid-walk,
    get_state and get_available_transitions; deactivate (by id) holds while the walk goes on
    commanding; configure, not available from inactive, is refused; activate (by label
    only) moves the joints again; shutdown ends the node by itself. Every transition
    taken is recorded from ~/transition_event. Then a bridge started with autostart false
    waits unconfigured until configured and activated."""
    from lifecycle_msgs.msg import Transition, TransitionEvent
    from lifecycle_msgs.srv import ChangeState, GetAvailableTransitions, GetState
    procs, peer, out = start_flowing(bin_dir, params)
    if not out["flowing"]:
        return out
    events = []
    peer.node.create_subscription(TransitionEvent, "/joint_bridge/transition_event", lambda m: events.append(
        {"id": m.transition.id, "label": m.transition.label, "start": m.start_state.label, "goal": m.goal_state.label}), 10)

    def state(attempt=30.0):
        # A query, safe to ask again: a fresh bridge may take seconds to match a client
        # created before it started (RustDDS discovery), and a lost reply is asked again.
        end = time.monotonic() + 30.0
        while time.monotonic() < end:
            r = peer.call(GetState, "/joint_bridge/get_state", GetState.Request(), timeout=attempt)
            if r is not None:
                return r.current_state.label
        return None

    def change(id_, label=""):
        r = peer.call(ChangeState, "/joint_bridge/change_state",
                      ChangeState.Request(transition=Transition(id=id_, label=label)))
        return None if r is None else bool(r.success)

    def available():
        r = peer.call(GetAvailableTransitions, "/joint_bridge/get_available_transitions",
                      GetAvailableTransitions.Request())
        return None if r is None else [[t.transition.id, t.transition.label, t.goal_state.label]
                                       for t in r.available_transitions]

    peer.walk(0)  # until stopped
    first = peer.states[-1]["position"]
    out["moving"] = peer.spin(30.0, lambda: peer.states[-1]["position"] != first)
    peer.spin(1.5)
    out["state_first"] = state()
    out["available_active"] = available()
    out["deactivate"] = change(Transition.TRANSITION_DEACTIVATE)
    out["deactivate_answered_t"] = time.time()  # the clock of the joint_states stamps
    out["state_deactivated"] = state()
    out["available_inactive"] = available()
    out["configure_from_inactive"] = change(Transition.TRANSITION_CONFIGURE)
    peer.spin(2.0)
    out["activate_t"] = time.time()
    out["activate"] = change(0, "activate")
    out["activate_answered_t"] = time.time()
    out["state_activated"] = state()
    peer.spin(1.5)
    out["shutdown_t"] = time.time()
    out["shutdown"] = change(Transition.TRANSITION_ACTIVE_SHUTDOWN)
    bridge = procs["joint_bridge"]
    end = time.monotonic() + 10.0
    while bridge.poll() is None and time.monotonic() < end:
        peer.spin(0.1)
    out["bridge_exited_by_itself"] = bridge.poll() is not None
    peer.spin(0.5)
    out.update(states=peer.states, rosout=peer.rosout, events=list(events))
    out["exits"] = stop_nodes(procs)
    # A bridge for a lifecycle manager: autostart false.
    bridge_only = start_nodes(bin_dir, params, {"joint_bridge": ["-p", "autostart:=false"]}, only=["joint_bridge"])
    del peer.__dict__["clients"]
    rosout_from = len(peer.rosout)
    n_states = len(peer.states)
    out["manual_state_first"] = state(attempt=2.0)
    out["manual_available"] = available()
    peer.spin(1.0)
    out["manual_states_unconfigured"] = len(peer.states) - n_states
    out["manual_configure"] = change(Transition.TRANSITION_CONFIGURE)
    out["manual_state_configured"] = state()
    n_states = len(peer.states)
    peer.spin(1.0)
    out["manual_states_inactive"] = len(peer.states) - n_states
    out["manual_activate"] = change(Transition.TRANSITION_ACTIVATE)
    out["manual_state_activated"] = state()
    out["manual_rosout"] = [r for r in peer.rosout[rosout_from:] if r["name"] == "joint_bridge"]
    out["manual_exits"] = stop_nodes(bridge_only)
    return out


def scenario_clock(bin_dir, params):
    """The planner on simulated time, its /clock published the way `ros2 bag play --clock`
    and most simulators publish it: best effort (rclcpp's ClockQoS, depth 1), 4 s of 10 ms
    steps, then the last value said again five times, 50 ms apart, as a lockstep simulator
    waiting for its answer does. Records the /gait/phase stamps it publishes and the clock
    values sent (each once)."""
    from rosgraph_msgs.msg import Clock
    from builtin_interfaces.msg import Time
    procs = start_nodes(bin_dir, params, {"gait_planner": ["-p", "use_sim_time:=true"]}, only=["gait_planner"])
    peer = Peer()
    clock_qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
    pub = peer.node.create_publisher(Clock, "/clock", clock_qos)
    out = {"sent": []}
    out["matched"] = peer.spin(20.0, lambda: pub.get_subscription_count() > 0)
    ns = 5_000_000_000
    end = time.monotonic() + 4.0
    while time.monotonic() < end:
        ns += 10_000_000
        pub.publish(Clock(clock=Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)))
        out["sent"].append(ns)
        peer.spin(0.01)
    for _ in range(5):
        pub.publish(Clock(clock=Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)))
        peer.spin(0.05)
    peer.spin(0.5)
    out["phase_stamps"] = [p["stamp"] for p in peer.phases]
    out["exits"] = stop_nodes(procs)
    return out


def scenario_discovery_off(bin_dir, params):
    """ROS_AUTOMATIC_DISCOVERY_RANGE=OFF as ROS 2 Jazzy's rmw_fastrtps means it: no discovery
    at all. The IK node OFF is never seen by this rclpy peer (LOCALHOST, which announces
    itself to every participant on this machine), while the planner, LOCALHOST, is seen and
    walked by it (the control). Records what the peer's graph lists."""
    procs = start_nodes(bin_dir, params, only=["gait_planner", "ik_solver"],
                        env={"ik_solver": {"ROS_AUTOMATIC_DISCOVERY_RANGE": "OFF"}})
    peer = Peer()
    out = {"planner_seen": peer.spin(20.0, lambda: "gait_planner" in peer.node_names())}
    out["walk_command_matched"] = peer.wait_for_subscribers(peer.walk_pub, timeout=10.0)
    peer.walk(2)
    out["walked"] = peer.spin(10.0, lambda: any(p["phase"] != "idle" for p in peer.phases))
    peer.spin(3.0)  # the IK node has had as long as the planner, and more
    out["nodes_seen"] = peer.node_names()
    out["ankle_targets_subscribers"] = peer.node.count_subscribers("/gait/ankle_targets")
    out["exits"] = stop_nodes(procs)
    return out


def scenario_launch(bin_dir, params):
    biped = os.path.join(bin_dir, "biped")
    log_dir = os.environ.get("BIPED_TEST_LOG_DIR", "/tmp/biped-launch-test")
    launcher = subprocess.Popen([biped, "launch", "--log-dir", log_dir], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    STARTED.append(launcher)
    peer = Peer()
    global NODES
    NODES = NODES + ["robot_state_publisher"]
    out = {"nodes_seen": peer.wait_for_nodes(30.0), "node_names": peer.node_names()}
    out.update(late_joiner(peer))
    stdout = stop_launcher(launcher, out)
    out["launcher_stdout"] = stdout
    pids = [int(line.split("(pid ")[1].split(")")[0]) for line in stdout.splitlines() if "(pid " in line]
    out["pids"] = pids
    alive = []
    for pid in pids:
        try:
            os.kill(pid, 0)
            alive.append(pid)
        except ProcessLookupError:
            pass
    out["alive_after"] = alive
    # A launcher killed outright: its nodes notice and stop by themselves.
    launcher = subprocess.Popen([biped, "launch", "--log-dir", log_dir + "-kill"], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    STARTED.append(launcher)
    pids2 = []
    while len(pids2) < len(NODES):
        line = launcher.stdout.readline()
        if not line:
            break
        if "(pid " in line:
            pids2.append(int(line.split("(pid ")[1].split(")")[0]))
    time.sleep(1.0)
    launcher.kill()
    launcher.wait()
    deadline = time.monotonic() + 5.0
    while time.monotonic() < deadline:
        still = []
        for pid in pids2:
            try:
                os.kill(pid, 0)
                # A zombie child of the killed launcher is reparented and reaped by init.
                with open(f"/proc/{pid}/stat") as f:
                    if f.read().split()[2] != "Z":
                        still.append(pid)
            except (ProcessLookupError, FileNotFoundError):
                pass
        if not still:
            break
        time.sleep(0.1)
    out["pids_after_kill"] = pids2
    out["alive_after_kill"] = still
    for pid in still:
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            out[f"{name}_gone_before_kill"] = pid
            break
    return out


def late_joiner(peer, timeout=30.0):
    """A ROS node started after the fleet has published `robot_description` and
    `/tf_static` (its own DDS participant, as RViz or `ros2 topic echo` started later would
    be) subscribes to them with transient local durability, as RViz's RobotModel display and
    tf2's listener do: what it gets. The test's peer keeps spinning meanwhile."""
    from rclpy.qos import DurabilityPolicy
    from std_msgs.msg import String
    from tf2_msgs.msg import TFMessage

    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
    got = {"robot_description": [], "tf_static": []}
    ctx = rclpy.Context()
    ctx.init()
    late = rclpy.create_node("late_joiner", context=ctx)
    executor = rclpy.executors.SingleThreadedExecutor(context=ctx)
    executor.add_node(late)
    late.create_subscription(String, "/robot_description", lambda m: got["robot_description"].append(m.data), latched)
    late.create_subscription(TFMessage, "/tf_static", lambda m: got["tf_static"].append(
        [{"parent": t.header.frame_id, "child": t.child_frame_id,
          "xyz": [t.transform.translation.x, t.transform.translation.y, t.transform.translation.z],
          "q": [t.transform.rotation.x, t.transform.rotation.y, t.transform.rotation.z, t.transform.rotation.w]}
         for t in m.transforms]), latched)
    try:
        end = time.monotonic() + timeout
        while time.monotonic() < end and not (got["robot_description"] and got["tf_static"]):
            executor.spin_once(timeout_sec=0.02)
            rclpy.spin_once(peer.node, timeout_sec=0.001)
        # Anything more (a second copy) would show here.
        end = time.monotonic() + 0.5
        while time.monotonic() < end:
            executor.spin_once(timeout_sec=0.02)
    finally:
        executor.shutdown()
        late.destroy_node()
        ctx.shutdown()
    return got


def stop_launcher(launcher, out):
    """Ctrl-C to `biped launch`, as a user would; its exit code and stderr tail into out.
    Returns what it printed on stdout."""
    launcher.send_signal(signal.SIGINT)
    try:
        stdout, stderr = launcher.communicate(timeout=20)
    except subprocess.TimeoutExpired:
        launcher.kill()
        stdout, stderr = launcher.communicate()
    out["launcher_returncode"] = launcher.returncode
    out["launcher_stderr"] = stderr[-2000:]
    return stdout


class Launcher:
    """`biped launch ARGS` watched as a supervisor test needs it: its stdout read line by
    line as it comes (the pids of started and restarted nodes), Ctrl-C at the end."""

    def __init__(self, bin_dir, args):
        import threading
        self.proc = subprocess.Popen([os.path.join(bin_dir, "biped"), "launch"] + args,
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        STARTED.append(self.proc)
        self.lines = []
        threading.Thread(target=lambda: [self.lines.append(line) for line in self.proc.stdout],
                         daemon=True).start()

    def pid_of(self, name, nth=0):
        """The pid of `name`'s nth start (0: the launch, 1: the first restart), if seen."""
        found = [int(line.split("(pid ")[1].split(",")[0].split(")")[0]) for line in list(self.lines)
                 if f" {name} (pid " in line and ("started" in line or "restarted" in line)]
        return found[nth] if len(found) > nth else None

    def stop(self, out):
        """Ctrl-C, as a user would; exit code, stderr and stdout into out."""
        self.proc.send_signal(signal.SIGINT)
        try:
            self.proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        out["launcher_returncode"] = self.proc.returncode
        out["launcher_stderr"] = self.proc.stderr.read()[-3000:]
        time.sleep(0.2)
        out["launcher_stdout"] = "".join(self.lines)


def scenario_supervise(bin_dir, params):
    """`biped launch` supervising: mid-walk, `kill -9` of the IK node, later of the joint
    bridge; each comes back (the launcher restarts it) while the other nodes run on. Records
    joint_states, the kill times and what the launcher printed."""
    log_dir = os.environ.get("BIPED_TEST_LOG_DIR", "/tmp/biped-launch-test") + "-supervise"
    launcher = Launcher(bin_dir, ["--log-dir", log_dir, "--respawn-delay", "0.5"])
    pid_of = launcher.pid_of
    peer = Peer()
    out = {"nodes_seen": peer.wait_for_nodes(30.0)}
    out["matched"] = peer.wait_for_subscribers(peer.walk_pub)
    out["flowing"] = peer.wait_for_flow()
    out["flow_diag"] = getattr(peer, "flow_diag", None)
    if not out["flowing"]:
        launcher.stop(out)
        return out
    peer.walk(0)  # until stopped
    first = peer.states[-1]["position"]
    out["moving"] = peer.spin(30.0, lambda: peer.states[-1]["position"] != first)
    peer.spin(1.0)
    for name in ["ik_solver", "joint_bridge"]:
        pid = pid_of(name)
        out[f"{name}_kill_t"] = time.time()  # the clock of the joint_states stamps
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            out[f"{name}_gone_before_kill"] = pid
            break
        out[f"{name}_restarted"] = peer.spin(20.0, lambda: pid_of(name, 1) is not None)
        out[f"{name}_restart_t"] = time.time()
        n_commands = len(peer.commands)
        # Commands and states flow again, from the restarted node.
        out[f"{name}_flowing_again"] = peer.spin(20.0, lambda: len(peer.commands) > n_commands + 50
                                                 and peer.states[-1]["t"] > out[f"{name}_restart_t"])
        peer.spin(1.5)
    out["launcher_alive"] = launcher.proc.poll() is None
    out.update(states=peer.states, rosout=[r for r in peer.rosout if r["level"] >= 30])
    launcher.stop(out)
    return out


def scenario_sim(bin_dir, params, composed=False):
    """`biped launch --backend sim`: the simulator in real time, watched and commanded by a
    plain rclpy node (no use_sim_time), as a user with RViz or Foxglove would. `composed`:
    the four nodes in one process (`--composed`)."""
    from geometry_msgs.msg import PointStamped, PolygonStamped, PoseStamped
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import Imu

    biped = os.path.join(bin_dir, "biped")
    log_dir = os.environ.get("BIPED_TEST_LOG_DIR", "/tmp/biped-launch-test") + "-sim"
    if composed:
        log_dir += "-composed"
    # The observer is up first, as RViz usually is.
    peer = Peer()
    peer.spin(1.0)
    launcher = subprocess.Popen([biped, "launch", "--backend", "sim", "--log-dir", log_dir]
                                + (["--composed"] if composed else []),
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    STARTED.append(launcher)
    n = peer.node
    qos = QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE)
    clock, base, cop, poly = [], [], [], []
    n.create_subscription(Clock, "/clock", lambda m: clock.append(
        {"wall": peer.now(), "t": m.clock.sec + m.clock.nanosec * 1e-9}), qos)
    n.create_subscription(PoseStamped, "/sim/base_pose", lambda m: base.append(
        {"stamp": stamp_ns(m.header), "frame": m.header.frame_id,
         "x": m.pose.position.x, "y": m.pose.position.y, "z": m.pose.position.z}), qos)
    n.create_subscription(PointStamped, "/sim/cop", lambda m: cop.append(
        {"stamp": stamp_ns(m.header), "x": m.point.x, "y": m.point.y}), qos)
    n.create_subscription(PolygonStamped, "/sim/support_polygon", lambda m: poly.append(
        {"stamp": stamp_ns(m.header), "points": len(m.polygon.points)}), qos)
    imu = []
    n.create_subscription(Imu, "/imu/data", lambda m: imu.append(
        {"frame": m.header.frame_id,
         "a": [m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z],
         "w": [m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z],
         "q": [m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w]}), qos)
    global NODES
    NODES = NODES + ["sim_bridge"]
    out = {"nodes_seen": peer.wait_for_nodes(60.0), "node_names": peer.node_names()}
    out["flowing"] = peer.spin(60.0, lambda: len(peer.states) > 20 and len(clock) > 20)
    out["matched"] = peer.wait_for_subscribers(peer.walk_pub, 20.0)
    # A second and a half standing (real time) before the walk: the IMU of a robot at rest.
    peer.spin(1.5)
    walk_from = len(clock)
    out["imu_standing"] = imu[-50:]
    imu_from = len(imu)
    peer.walk(2)
    out["walked"] = peer.spin(90.0, peer.idle_after_walking)
    out["imu_count"] = len(imu)
    out["imu_frames"] = sorted({m["frame"] for m in imu})
    out["imu_walking_max_rate"] = max((sum(x * x for x in m["w"]) ** 0.5 for m in imu[imu_from:]),
                                      default=0.0)
    peer.spin(1.0)
    out["clock"] = clock[walk_from:]
    out["base"] = base
    out["cop"] = cop[-200:]
    out["cop_count"] = len(cop)
    out["polygon_sizes"] = sorted({p["points"] for p in poly})
    last = peer.states[-1] if peer.states else {"name": [], "position": []}
    out["joint_state_names"] = last["name"]
    out["joint_state_stamps"] = [s["t"] for s in peer.states[-50:]]
    out["clock_values"] = [c["t"] for c in clock[-400:]]
    out["launcher_stdout"] = stop_launcher(launcher, out)
    out["rosout_errors"] = [m for m in peer.rosout if m["level"] >= 40]
    return out


def scenario_sim_kill(bin_dir, params):
    """The simulated robot in real time under `biped launch --backend sim`, mid-walk: an
    operator's ~/estop (std_srvs/Trigger) then ~/reset; then `kill -9` of the IK node, of the
    joint bridge and of the planner in turn, each restarted by the launcher. Records the
    simulator's ground-truth base pose, with the peer's clock for every event."""
    from geometry_msgs.msg import PoseStamped
    from std_srvs.srv import Trigger
    log_dir = os.environ.get("BIPED_TEST_LOG_DIR", "/tmp/biped-launch-test") + "-sim-kill"
    # The observer is up first, as in the sim scenario.
    peer = Peer()
    base = []
    qos = QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE)
    peer.node.create_subscription(PoseStamped, "/sim/base_pose", lambda m: base.append(
        {"t": peer.now(), "x": m.pose.position.x, "y": m.pose.position.y, "z": m.pose.position.z,
         "qx": m.pose.orientation.x, "qy": m.pose.orientation.y}), qos)
    peer.spin(1.0)
    launcher = Launcher(bin_dir, ["--backend", "sim", "--log-dir", log_dir, "--respawn-delay", "0.5"]
                        + (["--params", params] if params else []))
    pid_of = launcher.pid_of

    global NODES
    NODES = NODES + ["sim_bridge"]
    out = {"nodes_seen": peer.wait_for_nodes(60.0)}
    out["flowing"] = peer.spin(60.0, lambda: len(peer.states) > 20 and len(base) > 20)
    out["matched"] = peer.wait_for_subscribers(peer.walk_pub, 20.0)
    events = out["events"] = []
    if out["flowing"] and out["matched"]:
        peer.walk(0)  # until stopped
        out["walking"] = peer.spin(30.0, lambda: peer.phases and peer.phases[-1]["phase"] not in ("idle", "crouch"))
        peer.spin(3.0)
        events.append(["estop", peer.now()])
        r = peer.call(Trigger, "/joint_bridge/estop", Trigger.Request())
        out["estop"] = r is not None and r.success
        # A new client's endpoints take RustDDS seconds to discover: the stop is done by
        # the answer, not by the call.
        events.append(["estop answered", peer.now()])
        peer.spin(4.0)
        events.append(["reset", peer.now()])
        r = peer.call(Trigger, "/joint_bridge/reset", Trigger.Request())
        out["reset"] = r is not None and r.success
        peer.spin(3.0)
        for name in ["ik_solver", "joint_bridge", "gait_planner"]:
            events.append([f"kill {name}", peer.now()])
            os.kill(pid_of(name), signal.SIGKILL)
            out[f"{name}_restarted"] = peer.spin(20.0, lambda: pid_of(name, 1) is not None)
            events.append([f"restarted {name}", peer.now()])
            peer.spin(5.0)
        # The restarted planner holds: a walk asked now is refused, saying why. Asked again
        # every second, as a user would, until the new planner (its endpoints discovered
        # anew) answers.
        def refused():
            return any(r["name"].endswith("gait_planner") and "walk_command refused" in r["msg"]
                       for r in peer.rosout)
        for _ in range(15):
            peer.walk(2)
            if peer.spin(1.0, refused):
                break
        peer.spin(1.0)
        events.append(["end", peer.now()])
    out["base"] = base
    out["phases_tail"] = peer.phases[-5:]
    out["rosout"] = [r for r in peer.rosout if r["level"] >= 30]
    launcher.stop(out)
    return out


def scenario_teleop_sim(bin_dir, params):
    """A teleop driving the six-joint robot in the simulator (`biped launch --backend sim
    --robot`, real time): Twists at 10 Hz to turn left, then, two swings later, to walk
    forward, then none: the walk must end by itself. Records the ground truth and /odom."""
    from geometry_msgs.msg import PoseStamped
    from nav_msgs.msg import Odometry
    from std_msgs.msg import String

    biped = os.path.join(bin_dir, "biped")
    robot = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "data", "biped6_renamed.urdf")
    log_dir = os.environ.get("BIPED_TEST_LOG_DIR", "/tmp/biped-launch-test") + "-teleop-sim"
    peer = Peer()
    n = peer.node
    qos = QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE)
    base, odom, falls = [], [], []
    n.create_subscription(PoseStamped, "/sim/base_pose", lambda m: base.append(
        {"stamp": stamp_ns(m.header), "x": m.pose.position.x, "y": m.pose.position.y,
         "qz": m.pose.orientation.z, "qw": m.pose.orientation.w}), qos)
    n.create_subscription(Odometry, "/odom", lambda m: odom.append(
        {"stamp": stamp_ns(m.header), "x": m.pose.pose.position.x, "y": m.pose.pose.position.y,
         "qz": m.pose.pose.orientation.z, "qw": m.pose.pose.orientation.w}), qos)
    n.create_subscription(String, "/sim/fall", lambda m: falls.append(m.data), qos)
    peer.spin(1.0)
    launcher = subprocess.Popen([biped, "launch", "--backend", "sim", "--robot", robot, "--log-dir", log_dir]
                                + (["--params", params] if params else []),
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    STARTED.append(launcher)
    global NODES
    NODES = NODES + ["sim_bridge"]
    out = {"nodes_seen": peer.wait_for_nodes(60.0)}
    out["flowing"] = peer.spin(60.0, lambda: len(peer.states) > 20 and len(base) > 20)
    out["matched"] = peer.wait_for_subscribers(peer.cmd_vel_pub, 20.0)

    def swings():
        return {(p["step"], p["support"]) for p in peer.phases if p["phase"] in ("half_step", "step")}

    def stream(twist, until, timeout):
        end = time.monotonic() + timeout
        while time.monotonic() < end and not until():
            peer.cmd_vel_pub.publish(twist)
            peer.spin(0.1)

    def last_stamp():
        return peer.phases[-1]["stamp"] if peer.phases else 0

    # Each segment: the Twist, streamed until this many swings have begun in all.
    turn = Twist()
    turn.angular.z = 0.03
    ahead = Twist()
    ahead.linear.x = 0.01
    back = Twist()
    back.linear.x = -0.008
    arc = Twist()
    arc.linear.x = 0.01
    arc.angular.z = 0.03
    out["segments"] = []
    for name, twist, swings_after in [("turn", turn, 2), ("ahead", ahead, 5), ("back", back, 8), ("arc", arc, 11)]:
        start = last_stamp()
        stream(twist, lambda: len(swings()) >= swings_after, 60.0)
        out["segments"].append({"name": name, "from": start, "to": last_stamp()})
    out["swings_turning"] = sorted(list(s) for s in swings())
    out["finished"] = peer.spin(60.0, peer.idle_after_walking)
    peer.spin(1.0)
    out.update(phases=peer.phases, base=base, odom=odom, falls=falls, rosout=peer.rosout)
    stop_launcher(launcher, out)
    return out


def main():
    scenario, bin_dir = sys.argv[1], sys.argv[2]
    params = sys.argv[3] if len(sys.argv) > 3 else None
    try:
        run_scenario(scenario, bin_dir, params)
    finally:
        stop_started()


def stop_started():
    """Ctrl-C to every started process that still runs (a launcher stops its nodes), then
    kill what is left."""
    alive = [p for p in STARTED if p.poll() is None]
    for p in alive:
        p.send_signal(signal.SIGINT)
    for p in alive:
        try:
            p.wait(timeout=10)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


def run_scenario(scenario, bin_dir, params):
    result = {"walk": scenario_walk, "ik": scenario_ik,
              "ik_on_receive": lambda b, p: scenario_ik(b, p, on_receive=True),
              "teleop": scenario_teleop, "teleop_sim": scenario_teleop_sim,
              "watchdog": scenario_watchdog, "bridge_ticks": scenario_bridge_ticks, "estop": scenario_estop, "pause": scenario_pause,
              "lifecycle": scenario_lifecycle, "supervise": scenario_supervise, "clock": scenario_clock,
              "sim_kill": scenario_sim_kill, "discovery_off": scenario_discovery_off,
              "launch": scenario_launch,
              "sim": scenario_sim, "sim_delay": scenario_sim_delay,
              "sim_composed": lambda b, p: scenario_sim(b, p, composed=True)}[scenario](bin_dir, params)
    json.dump(result, sys.stdout)


if __name__ == "__main__":
    main()
