//! Service types (`std_srvs`, `lifecycle_msgs`), request and response in `.srv` field order so their CDR
//! encoding is the ROS one. An empty request carries rosidl's placeholder byte
//! (`structure_needs_at_least_one_member`), as every ROS implementation puts on the wire.

use serde::{Deserialize, Serialize};

use crate::msg::{LifecycleState, Transition, TransitionDescription};

/// A ROS service type: its package and name (`std_srvs`, `SetBool`).
pub trait RosService {
    /// The request.
    type Request: ros2_client::Message + Clone + 'static;
    /// The response.
    type Response: ros2_client::Message + 'static;
    /// Package, e.g. `std_srvs`.
    const PACKAGE: &'static str;
    /// Type name, e.g. `SetBool`.
    const NAME: &'static str;
    /// The type name for ros2-client.
    fn service_type_name() -> ros2_client::ServiceTypeName {
        ros2_client::ServiceTypeName::new(Self::PACKAGE, Self::NAME)
    }
}

/// A service type: a unit struct naming its package and its request and response types.
macro_rules! ros_service {
    ($(#[$doc:meta])* $name:ident, $pkg:literal, $req:ty, $resp:ty) => {
        $(#[$doc])*
        #[derive(Debug, Clone, Copy)]
        pub struct $name;
        impl RosService for $name {
            type Request = $req;
            type Response = $resp;
            const PACKAGE: &'static str = $pkg;
            const NAME: &'static str = stringify!($name);
        }
    };
}

/// An empty request (std_srvs/srv/Trigger, lifecycle_msgs/srv/GetState, ...).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct TriggerRequest {
    /// rosidl's placeholder member of an empty structure.
    pub structure_needs_at_least_one_member: u8,
}
impl ros2_client::Message for TriggerRequest {}

/// std_srvs/srv/Trigger and SetBool response.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct TriggerResponse {
    /// Whether it was done.
    pub success: bool,
    /// What was done, or why not.
    pub message: String,
}
impl ros2_client::Message for TriggerResponse {}

ros_service!(
    /// std_srvs/srv/Trigger: do something, say whether it was done.
    Trigger,
    "std_srvs",
    TriggerRequest,
    TriggerResponse
);

/// std_srvs/srv/SetBool request.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct SetBoolRequest {
    /// The value to set.
    pub data: bool,
}
impl ros2_client::Message for SetBoolRequest {}

ros_service!(
    /// std_srvs/srv/SetBool: set something on or off, say whether it was done.
    SetBool,
    "std_srvs",
    SetBoolRequest,
    TriggerResponse
);

/// lifecycle_msgs/srv/GetState response.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct GetStateResponse {
    /// The node's state.
    pub current_state: LifecycleState,
}
impl ros2_client::Message for GetStateResponse {}

ros_service!(
    /// lifecycle_msgs/srv/GetState: a managed node's state.
    GetState,
    "lifecycle_msgs",
    TriggerRequest,
    GetStateResponse
);

/// lifecycle_msgs/srv/ChangeState request.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ChangeStateRequest {
    /// The transition to take (by id, or by label with id 0).
    pub transition: Transition,
}
impl ros2_client::Message for ChangeStateRequest {}

/// lifecycle_msgs/srv/ChangeState response.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ChangeStateResponse {
    /// Whether the transition was taken.
    pub success: bool,
}
impl ros2_client::Message for ChangeStateResponse {}

ros_service!(
    /// lifecycle_msgs/srv/ChangeState: take a transition.
    ChangeState,
    "lifecycle_msgs",
    ChangeStateRequest,
    ChangeStateResponse
);

/// lifecycle_msgs/srv/GetAvailableTransitions response.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct GetAvailableTransitionsResponse {
    /// The transitions from the current state.
    pub available_transitions: Vec<TransitionDescription>,
}
impl ros2_client::Message for GetAvailableTransitionsResponse {}

ros_service!(
    /// lifecycle_msgs/srv/GetAvailableTransitions: what may be taken from the current state.
    GetAvailableTransitions,
    "lifecycle_msgs",
    TriggerRequest,
    GetAvailableTransitionsResponse
);
