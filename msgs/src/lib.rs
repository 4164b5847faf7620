//! The ROS 2 wire edge of the biped fleet.
//!
//! - [`msg`]: Rust types for our own `biped_msgs` interfaces (the ROS 2 package in this
//!   folder: `package.xml`, `CMakeLists.txt`, `msg/*.msg`) and for every standard type the
//!   nodes use, fields in `.msg` order so their CDR encoding is the ROS one. Each type names
//!   its ROS type and fields through [`RosMessage`]; a test checks them field by field against
//!   the types rosidl generates from the `.msg` files.
//! - [`srv`]: the service types the nodes serve (`std_srvs` Trigger and SetBool,
//!   `lifecycle_msgs` GetState, ChangeState and GetAvailableTransitions).
//! - [`type_description`]: what rosbag2 stores about a type: its RIHS01 hash and `ros2msg`
//!   definition, computed from the same field lists.
//!
//! Core crates never see these types: nodes convert at the edge. What nodes share beyond the
//! types (`--ros-args`, parameters, the DDS context, logging, ticks) is `node_runtime`'s.

pub mod msg;
pub mod srv;
pub mod type_description;

pub use msg::RosMessage;
