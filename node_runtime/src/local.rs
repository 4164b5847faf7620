//! Intra-process delivery for nodes composed in one process ([`crate::Host::composed`]), as
//! rclcpp's intra-process communication does it: a message published by one node of the
//! process reaches the process's other subscribers of that topic through a channel (one
//! clone, one wake-up of the subscriber's thread) instead of through DDS (a serialisation,
//! the DDS threads of both sides, a UDP datagram over loopback). Every message is still
//! published on DDS, so peers outside the process (RViz, rosbag2, `ros2 topic echo`) see
//! the same topics; subscribers inside the process drop the DDS copy of a message they
//! already got, by its publisher's GID, and still take every message from outside peers.
//!
//! [`Publisher`] and [`Subscription`] keep ros2-client's signatures, so a node's code is the
//! same alone or composed.

use std::any::Any;
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex, PoisonError};

use ros2_client::{Gid, MessageInfo};
use smol::channel::{Receiver, Sender};

use crate::error::RosError;

/// The process's topics that nodes composed in it publish or subscribe, by resolved name.
#[derive(Debug, Default)]
pub(crate) struct Bus {
    topics: Mutex<BTreeMap<String, Arc<dyn Any + Send + Sync>>>,
}

/// What a message arrives with on the bus: the message and its sender's GID.
type Sample<M> = (M, MessageInfo);

/// One topic of the bus.
#[derive(Debug)]
struct LocalTopic<M> {
    /// The publishers in this process (their DDS copies are dropped by local subscribers).
    publishers: Mutex<Vec<Gid>>,
    /// Each local subscriber's queue.
    subscribers: Mutex<Vec<Sender<Sample<M>>>>,
    /// The last message of a latched publisher, for a latched subscriber that comes later.
    latched: Mutex<Option<Sample<M>>>,
}

impl Bus {
    /// The topic `name` carrying `M`; an error if a node of the process uses the name for
    /// another type.
    fn topic<M: Send + 'static>(
        &self,
        name: &str,
        type_name: &str,
    ) -> Result<Arc<LocalTopic<M>>, RosError> {
        let mut topics = self.topics.lock().unwrap_or_else(PoisonError::into_inner);
        let entry = topics.entry(name.to_owned()).or_insert_with(|| {
            Arc::new(LocalTopic::<M> {
                publishers: Mutex::new(Vec::new()),
                subscribers: Mutex::new(Vec::new()),
                latched: Mutex::new(None),
            })
        });
        Arc::clone(entry)
            .downcast::<LocalTopic<M>>()
            .map_err(|_| RosError::Args(format!(
                "topic `{name}`: nodes composed in this process use it with different types (one of them {type_name})"
            )))
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

impl<M: Clone> LocalTopic<M> {
    fn is_local(&self, gid: &Gid) -> bool {
        lock(&self.publishers).contains(gid)
    }

    fn deliver(&self, message: &M, from: Gid, latched: bool) {
        let info = MessageInfo::new(None, None, 0, from, None);
        if latched {
            *lock(&self.latched) = Some((message.clone(), info.clone()));
        }
        lock(&self.subscribers).retain(|tx| {
            // A full queue drops its oldest message (keep last N); a closed one is a
            // subscription that is gone.
            tx.force_send((message.clone(), info.clone())).is_ok()
        });
    }
}

/// A publisher: on DDS always, and to the subscribers of its process when composed.
pub struct Publisher<M: RosMessageBound> {
    dds: ros2_client::Publisher<M>,
    local: Option<(Arc<LocalTopic<M>>, bool)>,
}

/// What a message type needs to travel on the bus.
pub trait RosMessageBound: biped_msgs::RosMessage + Send + 'static {}
impl<M: biped_msgs::RosMessage + Send + 'static> RosMessageBound for M {}

impl<M: RosMessageBound> std::fmt::Debug for Publisher<M> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Publisher")
            .field("type", &M::message_type_name())
            .field("intra_process", &self.local.is_some())
            .finish()
    }
}

impl<M: RosMessageBound> Publisher<M> {
    pub(crate) fn new(
        dds: ros2_client::Publisher<M>,
        bus: Option<&Bus>,
        name: &str,
        latched: bool,
    ) -> Result<Self, RosError> {
        let local = match bus {
            Some(bus) => {
                let topic = bus.topic::<M>(name, &format!("{}/msg/{}", M::PACKAGE, M::NAME))?;
                lock(&topic.publishers).push(dds.gid());
                Some((topic, latched))
            }
            None => None,
        };
        Ok(Self { dds, local })
    }

    /// Publishes `message`: first to the subscribers in this process, then on DDS.
    pub fn publish(&self, message: M) -> ros2_client::WriteResult<(), M> {
        if let Some((topic, latched)) = &self.local {
            topic.deliver(&message, self.dds.gid(), *latched);
        }
        self.dds.publish(message)
    }

    /// How many subscriptions take this publisher's messages: those of its process (when
    /// composed) and those matched on DDS, as `ros` (the node that made it) has discovered
    /// them. For a message costly to build that only viewers read (markers), as rclcpp
    /// nodes check `get_subscription_count()` before building theirs.
    pub fn subscription_count(&self, ros: &crate::RosNode) -> usize {
        let local = self.local.as_ref().map_or(0, |(topic, _)| {
            // A subscription gone leaves its queue closed until the next delivery.
            lock(&topic.subscribers)
                .iter()
                .filter(|tx| !tx.is_closed())
                .count()
        });
        local + self.dds.get_subscription_count(&ros.node)
    }

    /// The DDS publisher's GID (what subscribers' message info names).
    pub fn gid(&self) -> Gid {
        self.dds.gid()
    }
}

/// A subscription: DDS, and the publishers of its process when composed (their DDS copies
/// dropped).
pub struct Subscription<M: RosMessageBound> {
    dds: ros2_client::Subscription<M>,
    local: Option<LocalQueue<M>>,
}

/// A subscription's topic on the bus and its queue there.
type LocalQueue<M> = (Arc<LocalTopic<M>>, Receiver<Sample<M>>);

impl<M: RosMessageBound> std::fmt::Debug for Subscription<M> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Subscription")
            .field("type", &M::message_type_name())
            .field("intra_process", &self.local.is_some())
            .finish()
    }
}

impl<M: RosMessageBound> Subscription<M> {
    pub(crate) fn new(
        dds: ros2_client::Subscription<M>,
        bus: Option<&Bus>,
        name: &str,
        depth: usize,
        latched: bool,
    ) -> Result<Self, RosError> {
        let local = match bus {
            Some(bus) => {
                let topic = bus.topic::<M>(name, &format!("{}/msg/{}", M::PACKAGE, M::NAME))?;
                let (tx, rx) = smol::channel::bounded(depth.max(1));
                if latched && let Some(last) = lock(&topic.latched).clone() {
                    let _ = tx.force_send(last);
                }
                lock(&topic.subscribers).push(tx);
                Some((topic, rx))
            }
            None => None,
        };
        Ok(Self { dds, local })
    }

    /// True for the DDS copy of a message a publisher of this process delivered in-process.
    fn delivered_already(&self, info: &MessageInfo) -> bool {
        self.local
            .as_ref()
            .is_some_and(|(t, _)| t.is_local(&info.publisher_gid()))
    }

    /// The next DDS sample that is not a copy of a message already delivered in-process.
    fn take_dds(&self) -> ros2_client::ReadResult<Option<Sample<M>>> {
        loop {
            match self.dds.take()? {
                Some((_, info)) if self.delivered_already(&info) => {}
                other => return Ok(other),
            }
        }
    }

    /// The next message if one is waiting: first those from this process, then DDS.
    pub fn take(&self) -> ros2_client::ReadResult<Option<Sample<M>>> {
        if let Some((_, rx)) = &self.local
            && let Ok(sample) = rx.try_recv()
        {
            return Ok(Some(sample));
        }
        self.take_dds()
    }

    /// Waits for the next message, from this process or from DDS.
    pub async fn async_take(&self) -> ros2_client::ReadResult<Sample<M>> {
        use smol::future::FutureExt as _;
        let dds = async {
            loop {
                let (m, info) = self.dds.async_take().await?;
                if !self.delivered_already(&info) {
                    return Ok((m, info));
                }
            }
        };
        match &self.local {
            None => dds.await,
            Some((_, rx)) => {
                let local = async {
                    match rx.recv().await {
                        Ok(sample) => Ok(sample),
                        // The bus holds a sender for as long as the topic lives: never
                        // closed while this subscription exists, so wait on DDS alone.
                        Err(_) => std::future::pending().await,
                    }
                };
                local.or(dds).await
            }
        }
    }

    /// Hands each message to `handler` on the thread that receives it (the participant's
    /// DDS thread) instead of waking the node's thread: one thread wake-up a message
    /// instead of two. The handler must be short and must not wait ([`crate::on_receive`]).
    /// Refused for a node composed with others in one process (its in-process messages
    /// come through the bus, not a DDS thread).
    pub fn on_receive(
        self,
        handler: impl FnMut(crate::on_receive::Received<M>) + Send + 'static,
    ) -> Result<crate::on_receive::OnReceive<M>, RosError> {
        if self.local.is_some() {
            return Err(RosError::Args(format!(
                "a subscription to {}/msg/{} handled on its DDS thread: not for nodes composed in one process",
                M::PACKAGE,
                M::NAME
            )));
        }
        Ok(crate::on_receive::OnReceive::new(self.dds, handler))
    }
}
