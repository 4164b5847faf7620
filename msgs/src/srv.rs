//! Service types (`std_srvs`), request and response in `.srv` field order so their CDR
//! encoding is the ROS one. An empty request carries rosidl's placeholder byte
//! (`structure_needs_at_least_one_member`), as every ROS implementation puts on the wire.

use serde::{Deserialize, Serialize};

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

/// An empty request (std_srvs/srv/Trigger).
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

/// std_srvs/srv/Trigger: do something, say whether it was done.
#[derive(Debug, Clone, Copy)]
pub struct Trigger;
impl RosService for Trigger {
    type Request = TriggerRequest;
    type Response = TriggerResponse;
    const PACKAGE: &'static str = "std_srvs";
    const NAME: &'static str = "Trigger";
}

/// std_srvs/srv/SetBool request.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct SetBoolRequest {
    /// The value to set.
    pub data: bool,
}
impl ros2_client::Message for SetBoolRequest {}

/// std_srvs/srv/SetBool: set something on or off, say whether it was done.
#[derive(Debug, Clone, Copy)]
pub struct SetBool;
impl RosService for SetBool {
    type Request = SetBoolRequest;
    type Response = TriggerResponse;
    const PACKAGE: &'static str = "std_srvs";
    const NAME: &'static str = "SetBool";
}
