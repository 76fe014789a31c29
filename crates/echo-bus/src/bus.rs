//! The typed bus over a Zenoh session.

use std::marker::PhantomData;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use anyhow::{anyhow, Result};
use echo_msgs::{encode, now_ns, Header, Message};
use zenoh::sample::SampleKind;

use crate::inbox::{self, Inbox};
use crate::liveliness::AliveWatch;
use crate::shutdown::Shutdown;
use crate::{keys, topics, BusArgs, Ingress, RobotId, Stats, Topic};

/// A service's connection to the Echo network.
#[derive(Clone)]
pub struct Bus {
    session: zenoh::Session,
    robot: RobotId,
    service: String,
    source: String,
    stats: Arc<Stats>,
    max_clock_skew_ms: u64,
}

impl std::fmt::Debug for Bus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bus")
            .field("robot", &self.robot)
            .field("service", &self.service)
            .field("source", &self.source)
            .finish()
    }
}

/// Publisher of one typed topic; stamps schema, sequence number, source and robot id.
pub struct Publisher<M> {
    inner: zenoh::pubsub::Publisher<'static>,
    edge: &'static str,
    source: String,
    robot: String,
    seq: AtomicU64,
    stats: Arc<Stats>,
    _msg: PhantomData<fn(M)>,
}

impl Bus {
    /// Open a session for `service` with `args`.
    pub async fn open(args: &BusArgs, service: &str) -> Result<Bus> {
        let robot = args.robot_id()?;
        let session = zenoh::open(args.for_service(service).zenoh_config()?)
            .await
            .map_err(|e| anyhow!("opening Zenoh session: {e}"))?;
        let source = format!(
            "{service}-{}-{:04x}",
            std::process::id(),
            (now_ns() / 1000) & 0xffff
        );
        tracing::info!(%robot, service, zid = %session.zid(), "bus open");
        Ok(Bus {
            session,
            robot,
            service: service.to_string(),
            stats: Arc::new(Stats::new(service)),
            source,
            max_clock_skew_ms: args.max_clock_skew_ms(),
        })
    }

    /// The robot this bus is for.
    pub fn robot(&self) -> &RobotId {
        &self.robot
    }

    /// Service name.
    pub fn service(&self) -> &str {
        &self.service
    }

    /// This process's source id (sequence numbers are per source).
    pub fn source(&self) -> &str {
        &self.source
    }

    /// The service's counters.
    pub fn stats(&self) -> Arc<Stats> {
        self.stats.clone()
    }

    /// The underlying Zenoh session (for tools: raw subscriptions, queries).
    pub fn session(&self) -> &zenoh::Session {
        &self.session
    }

    /// A header from this service for `frame_id`, stamped now (sequence set at publish).
    pub fn header(&self, frame_id: &str) -> Header {
        Header::new(self.robot.as_str(), &self.source, frame_id)
    }

    /// Declare a typed publisher with the topic's QoS.
    pub async fn publisher<M: Message>(&self, topic: &Topic<M>) -> Result<Publisher<M>> {
        let d = topic.delivery;
        let inner = self
            .session
            .declare_publisher(topic.key.clone())
            .congestion_control(d.congestion_control())
            .priority(d.priority())
            .express(d.express())
            .await
            .map_err(|e| anyhow!("declaring publisher on {}: {e}", topic.key))?;
        Ok(Publisher {
            inner,
            edge: topic.name,
            source: self.source.clone(),
            robot: topic
                .robot
                .as_ref()
                .unwrap_or(&self.robot)
                .as_str()
                .to_string(),
            seq: AtomicU64::new(0),
            stats: self.stats.clone(),
            _msg: PhantomData,
        })
    }

    /// Subscribe to a typed topic. Every payload goes through [`Ingress`]; accepted messages
    /// land in the returned [`Inbox`] with the topic's delivery policy.
    pub async fn subscribe<M: Message>(&self, topic: &Topic<M>) -> Result<Inbox<M>> {
        let (tx, inbox) = inbox::channel(topic.delivery, topic.name, self.stats.clone());
        let ingress = Mutex::new(
            Ingress::new(topic.name, topic.robot.clone(), self.stats.clone())
                .with_max_clock_skew_ms(self.max_clock_skew_ms),
        );
        let sub = self
            .session
            .declare_subscriber(topic.key.clone())
            .callback(move |sample| {
                if sample.kind() != SampleKind::Put {
                    return;
                }
                let bytes = sample.payload().to_bytes();
                let accepted = ingress
                    .lock()
                    .unwrap_or_else(|e| e.into_inner())
                    .accept::<M>(&bytes);
                if let Ok(msg) = accepted {
                    tx.push(msg);
                }
            })
            .await
            .map_err(|e| anyhow!("declaring subscriber on {}: {e}", topic.key))?;
        Ok(inbox.with_guard(Box::new(sub)))
    }

    /// Declare this service's liveliness token `echo/<robot>/alive/<service>`.
    pub async fn declare_alive(&self) -> Result<zenoh::liveliness::LivelinessToken> {
        let key = keys::alive(&self.robot, &self.service);
        self.session
            .liveliness()
            .declare_token(key.clone())
            .await
            .map_err(|e| anyhow!("declaring liveliness token {key}: {e}"))
    }

    /// Watch liveliness tokens matching `key` (e.g. [`keys::alive_all`]).
    pub async fn watch_alive(&self, key: &str) -> Result<AliveWatch> {
        AliveWatch::declare(&self.session, key).await
    }

    /// Services alive now, as (robot, service) pairs, from a liveliness query on `key`.
    pub async fn alive_now(&self, key: &str, timeout: Duration) -> Result<Vec<(String, String)>> {
        let replies = self
            .session
            .liveliness()
            .get(key)
            .timeout(timeout)
            .await
            .map_err(|e| anyhow!("liveliness query {key}: {e}"))?;
        let mut out = vec![];
        while let Ok(reply) = replies.recv_async().await {
            if let Ok(sample) = reply.result() {
                if let Some((r, s)) = keys::parse_alive(sample.key_expr().as_str()) {
                    out.push((r.to_string(), s.to_string()));
                }
            }
        }
        out.sort();
        out.dedup();
        Ok(out)
    }

    /// Publish this service's [`echo_msgs::ServiceStatus`] every `period` until `shutdown`,
    /// and once more at the end.
    pub fn spawn_status_reporter(
        &self,
        period: Duration,
        mut shutdown: Shutdown,
    ) -> tokio::task::JoinHandle<()> {
        let bus = self.clone();
        tokio::spawn(async move {
            let topic = topics::service_status(&bus.robot, &bus.service);
            let publisher = match bus.publisher(&topic).await {
                Ok(p) => p,
                Err(e) => {
                    tracing::error!("status publisher: {e:#}");
                    return;
                }
            };
            let mut tick = tokio::time::interval(period);
            loop {
                tokio::select! {
                    _ = tick.tick() => {}
                    _ = shutdown.wait() => {
                        let _ = publisher.put(bus.stats.to_status(bus.header(""))).await;
                        return;
                    }
                }
                if let Err(e) = publisher.put(bus.stats.to_status(bus.header(""))).await {
                    tracing::warn!("status publish failed: {e:#}");
                }
            }
        })
    }

    /// Close the session (liveliness tokens disappear at once for the peers).
    pub async fn close(self) -> Result<()> {
        self.session
            .close()
            .await
            .map_err(|e| anyhow!("closing session: {e}"))
    }
}

impl<M: Message> Publisher<M> {
    /// Publish `msg`: sets schema, the next sequence number, source and (if empty) robot id;
    /// keeps `stamp_ns` as the producer set it.
    pub async fn put(&self, mut msg: M) -> Result<()> {
        let h = msg.header_mut();
        h.schema = echo_msgs::SCHEMA_VERSION;
        h.seq = self.seq.fetch_add(1, Ordering::Relaxed);
        h.source.clone_from(&self.source);
        if h.robot_id.is_empty() {
            h.robot_id.clone_from(&self.robot);
        }
        let bytes = encode(&msg);
        self.inner
            .put(bytes)
            .await
            .map_err(|e| anyhow!("publishing {}: {e}", self.edge))?;
        self.stats.published(self.edge);
        Ok(())
    }

    /// Publish raw bytes on this topic's key, bypassing encoding (fault-injection tools only).
    pub async fn put_raw(&self, bytes: Vec<u8>) -> Result<()> {
        self.inner
            .put(bytes)
            .await
            .map_err(|e| anyhow!("publishing raw {}: {e}", self.edge))
    }
}
