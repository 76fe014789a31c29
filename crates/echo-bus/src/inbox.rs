//! Receiver queues with the edge's delivery policy.

use std::collections::VecDeque;
use std::sync::{Arc, Condvar, Mutex};
use std::time::Instant;

use tokio::sync::Notify;

use crate::{Delivery, Stats};

/// A message with its receipt time on the receiver's monotonic clock.
#[derive(Debug, Clone)]
pub struct Received<M> {
    /// The decoded, validated message.
    pub msg: M,
    /// When it was accepted (receiver's clock).
    pub at: Instant,
}

#[derive(Debug)]
struct Queue<M> {
    items: Mutex<QueueState<M>>,
    space: Condvar,
    ready: Notify,
}

#[derive(Debug)]
struct QueueState<M> {
    items: VecDeque<Received<M>>,
    closed: bool,
}

/// Consumer end of a subscription: yields accepted messages in arrival order.
#[derive(Debug)]
pub struct Inbox<M> {
    queue: Arc<Queue<M>>,
    _guard: Option<Box<dyn std::any::Any + Send + Sync>>,
}

/// Producer end (lives in the Zenoh callback or in tests).
#[derive(Debug)]
pub struct InboxSender<M> {
    queue: Arc<Queue<M>>,
    delivery: Delivery,
    edge: &'static str,
    stats: Arc<Stats>,
}

impl<M> Clone for InboxSender<M> {
    fn clone(&self) -> Self {
        InboxSender {
            queue: self.queue.clone(),
            delivery: self.delivery,
            edge: self.edge,
            stats: self.stats.clone(),
        }
    }
}

/// A connected sender/inbox pair with `delivery`'s policy; drops are counted on `edge`.
pub fn channel<M>(
    delivery: Delivery,
    edge: &'static str,
    stats: Arc<Stats>,
) -> (InboxSender<M>, Inbox<M>) {
    let queue = Arc::new(Queue {
        items: Mutex::new(QueueState {
            items: VecDeque::with_capacity(delivery.depth()),
            closed: false,
        }),
        space: Condvar::new(),
        ready: Notify::new(),
    });
    (
        InboxSender {
            queue: queue.clone(),
            delivery,
            edge,
            stats,
        },
        Inbox {
            queue,
            _guard: None,
        },
    )
}

impl<M> InboxSender<M> {
    /// Enqueue. Sensor/status edges drop the oldest entry when full (counted); command edges
    /// wait for space (back-pressure through Zenoh's blocking congestion control).
    pub fn push(&self, msg: M) {
        let item = Received {
            msg,
            at: Instant::now(),
        };
        let depth = self.delivery.depth();
        let mut g = self.queue.items.lock().unwrap_or_else(|e| e.into_inner());
        if g.closed {
            return;
        }
        match self.delivery {
            Delivery::CommandBlock { .. } => {
                while g.items.len() >= depth && !g.closed {
                    g = self.queue.space.wait(g).unwrap_or_else(|e| e.into_inner());
                }
            }
            _ => {
                while g.items.len() >= depth {
                    g.items.pop_front();
                    self.stats.dropped(self.edge, 1);
                }
            }
        }
        g.items.push_back(item);
        drop(g);
        self.queue.ready.notify_one();
    }
}

impl<M> Inbox<M> {
    pub(crate) fn with_guard(mut self, guard: Box<dyn std::any::Any + Send + Sync>) -> Self {
        self._guard = Some(guard);
        self
    }

    /// Next message, waiting for one; `None` once closed and empty.
    pub async fn recv(&self) -> Option<Received<M>> {
        loop {
            let notified = self.queue.ready.notified();
            if let Some(x) = self.try_recv() {
                return Some(x);
            }
            if self
                .queue
                .items
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .closed
            {
                return None;
            }
            notified.await;
        }
    }

    /// Next message if one is queued.
    pub fn try_recv(&self) -> Option<Received<M>> {
        let mut g = self.queue.items.lock().unwrap_or_else(|e| e.into_inner());
        let item = g.items.pop_front();
        if item.is_some() {
            self.queue.space.notify_one();
        }
        item
    }

    /// Everything queued now, oldest first.
    pub fn drain(&self) -> Vec<Received<M>> {
        let mut g = self.queue.items.lock().unwrap_or_else(|e| e.into_inner());
        let v: Vec<_> = g.items.drain(..).collect();
        self.queue.space.notify_all();
        v
    }
}

impl<M> Drop for Inbox<M> {
    fn drop(&mut self) {
        let mut g = self.queue.items.lock().unwrap_or_else(|e| e.into_inner());
        g.closed = true;
        g.items.clear();
        self.queue.space.notify_all();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sensor_edges_drop_oldest_and_count() {
        let stats = Arc::new(Stats::new("t"));
        let (tx, rx) = channel::<u32>(Delivery::SensorDropOldest { depth: 3 }, "s", stats.clone());
        for i in 0..5 {
            tx.push(i);
        }
        let got: Vec<u32> = rx.drain().into_iter().map(|r| r.msg).collect();
        assert_eq!(got, vec![2, 3, 4]);
        assert_eq!(stats.dropped_count("s"), 2);
    }

    #[test]
    fn command_edges_block_instead_of_dropping() {
        let stats = Arc::new(Stats::new("t"));
        let (tx, rx) = channel::<u32>(Delivery::CommandBlock { depth: 2 }, "c", stats.clone());
        let producer = std::thread::spawn(move || {
            for i in 0..10 {
                tx.push(i);
            }
        });
        let mut got = vec![];
        while got.len() < 10 {
            if let Some(r) = rx.try_recv() {
                got.push(r.msg);
            } else {
                std::thread::yield_now();
            }
        }
        producer.join().unwrap();
        assert_eq!(got, (0..10).collect::<Vec<_>>());
        assert_eq!(stats.dropped_count("c"), 0);
    }
}
