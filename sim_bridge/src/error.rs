//! Errors of the simulator. Every variant names the joint, key, body or value at fault.

/// Why a simulation could not be built or run.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// The URDF does not give a biped robot model (parse error, broken tree, no legs).
    #[error("robot model: {0}")]
    Model(#[from] ik_solver::ModelError),
    /// MuJoCo refused the model while parsing or compiling it.
    #[error("MuJoCo cannot {stage} the model: {message}")]
    Mujoco {
        /// "parse" or "compile" (or what else was being done).
        stage: &'static str,
        /// MuJoCo's message.
        message: String,
    },
    /// Something of the robot model is missing from the compiled MuJoCo model.
    #[error("the MuJoCo model has no {kind} `{name}`")]
    Missing {
        /// "joint", "body", "actuator", "geom".
        kind: &'static str,
        /// Its name.
        name: String,
    },
    /// A joint map that does not fit the URDF or the MJCF scene: the key of the map (or
    /// `(scene)` / `(file)`) and why.
    #[error("joint map `{key}`: {why}")]
    JointMap {
        /// The key, as written in the YAML file (`joints.l_knee.actuator`).
        key: String,
        /// What is wrong.
        why: String,
    },
    /// A scene actuator that is not a plain position servo on its joint.
    #[error("MJCF actuator `{actuator}` {why}")]
    Servo {
        /// The actuator.
        actuator: String,
        /// What is wrong.
        why: String,
    },
    /// A configuration value out of its bounds.
    #[error("sim config `{key}` = {value}: {why}")]
    Config {
        /// The key, as written in the YAML file.
        key: &'static str,
        /// The value given.
        value: f64,
        /// The bounds or the reason.
        why: String,
    },
    /// The configuration text does not parse.
    #[error("sim config: {0}")]
    ConfigParse(String),
    /// A joint without a usable torque limit and no `torque_limit_nm` configured.
    #[error(
        "joint `{joint}`: URDF effort {effort_nm} N·m is not a positive torque limit; set torque_limit_nm"
    )]
    TorqueLimit {
        /// The joint.
        joint: String,
        /// Its URDF effort.
        effort_nm: f64,
    },
    /// A joint position or target that is NaN or infinite.
    #[error("joint `{joint}`: {what} {value} rad is not finite")]
    NonFinite {
        /// The joint.
        joint: String,
        /// "target", "position", ...
        what: &'static str,
        /// The value.
        value: f64,
    },
    /// A base pose that is NaN or infinite.
    #[error("base pose is not finite: {0}")]
    NonFiniteBase(String),
    /// A joint vector of the wrong length.
    #[error("{what}: {got} values for {expected} joints")]
    JointCount {
        /// What was given.
        what: &'static str,
        /// Joints of the robot.
        expected: usize,
        /// Values given.
        got: usize,
    },
    /// A time that is not finite or lies before the simulation's time.
    #[error("time {t_s} s is not finite or before the simulation time {now_s} s")]
    Time {
        /// The time asked for.
        t_s: f64,
        /// The simulation time.
        now_s: f64,
    },
    /// The physics blew up (non-finite state, or MuJoCo's bad-acceleration warning).
    #[error("the simulation diverged at t = {t_s} s: {why}")]
    Diverged {
        /// Simulation time.
        t_s: f64,
        /// What was seen.
        why: String,
    },
    /// A plan that cannot be played (empty, joint vectors of the wrong length, times not
    /// increasing).
    #[error("plan: {0}")]
    Plan(String),
}
