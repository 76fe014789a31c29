//! Foxglove output: scenes as `foxglove.SceneUpdate` on [`SCENE_TOPIC`], the robot's link frames
//! as `foxglove.FrameTransforms` on [`TF_TOPIC`] (protobuf, with their schemas), in MCAP files
//! ([`FoxgloveRecorder`], [`convert_recording`]) or live over the Foxglove WebSocket protocol
//! ([`LiveServer`]). The bus's own JSON messages are kept on their key expressions, so one file
//! holds the raw data and the picture of it.

use std::collections::{BTreeMap, HashMap};
use std::io::{Seek, Write};
use std::path::Path;
use std::sync::{Arc, Mutex};

use foxglove::messages::{
    scene_entity_deletion, Color, CylinderPrimitive, FrameTransform, FrameTransforms,
    LinePrimitive, Point3, Pose, Quaternion, SceneEntity, SceneEntityDeletion, SceneUpdate,
    SpherePrimitive, TextPrimitive, Timestamp, Vector3,
};
use foxglove::Encode;
use nalgebra::{Isometry3, UnitQuaternion};

use crate::builder::{SceneBuilder, SceneOptions};
use crate::scene::{Primitive, Rgba, Scene};
use crate::SceneError;

/// Topic of the scene updates.
pub const SCENE_TOPIC: &str = "/scene";
/// Topic of the robot's link frames.
pub const TF_TOPIC: &str = "/tf";

/// Nanoseconds since the Unix epoch as a Foxglove timestamp.
pub fn timestamp(ns: u64) -> Timestamp {
    let sec = u32::try_from(ns / 1_000_000_000).unwrap_or(u32::MAX);
    Timestamp::new(sec, (ns % 1_000_000_000) as u32)
}

fn color(c: Rgba) -> Option<Color> {
    Some(Color {
        r: c.r as f64,
        g: c.g as f64,
        b: c.b as f64,
        a: c.a as f64,
    })
}

fn point(p: [f64; 3]) -> Point3 {
    Point3 {
        x: p[0],
        y: p[1],
        z: p[2],
    }
}

fn pose(position: [f64; 3], q: UnitQuaternion<f64>) -> Option<Pose> {
    Some(Pose {
        position: Some(Vector3 {
            x: position[0],
            y: position[1],
            z: position[2],
        }),
        orientation: Some(Quaternion {
            x: q.i,
            y: q.j,
            z: q.k,
            w: q.w,
        }),
    })
}

fn sphere(centre: [f64; 3], radius: f64, c: Rgba) -> SpherePrimitive {
    let d = 2.0 * radius;
    SpherePrimitive {
        pose: pose(centre, UnitQuaternion::identity()),
        size: Some(Vector3 { x: d, y: d, z: d }),
        color: color(c),
    }
}

/// A scene as one SceneUpdate: every entity of the previous update is deleted first, so people
/// who left disappear. A capsule becomes a cylinder and two spheres.
pub fn scene_update(scene: &Scene) -> SceneUpdate {
    let ts = timestamp(scene.time_ns);
    let entities = scene
        .entities
        .iter()
        .map(|e| {
            let mut out = SceneEntity {
                timestamp: Some(ts),
                frame_id: scene.frame_id.clone(),
                id: e.id.clone(),
                frame_locked: true,
                ..Default::default()
            };
            for p in &e.primitives {
                match p {
                    Primitive::Sphere {
                        centre,
                        radius,
                        color: c,
                    } => out.spheres.push(sphere(*centre, *radius, *c)),
                    Primitive::Capsule {
                        a,
                        b,
                        radius,
                        color: c,
                    } => {
                        let (va, vb) = (nalgebra::Vector3::from(*a), nalgebra::Vector3::from(*b));
                        let axis = vb - va;
                        let len = axis.norm();
                        if len > 1e-9 {
                            let q =
                                UnitQuaternion::rotation_between(&nalgebra::Vector3::z(), &axis)
                                    .unwrap_or_else(|| {
                                        UnitQuaternion::from_axis_angle(
                                            &nalgebra::Vector3::x_axis(),
                                            std::f64::consts::PI,
                                        )
                                    });
                            let d = 2.0 * radius;
                            out.cylinders.push(CylinderPrimitive {
                                pose: pose(((va + vb) / 2.0).into(), q),
                                size: Some(Vector3 { x: d, y: d, z: len }),
                                bottom_scale: 1.0,
                                top_scale: 1.0,
                                color: color(*c),
                            });
                            out.spheres.push(sphere(*b, *radius, *c));
                        }
                        out.spheres.push(sphere(*a, *radius, *c));
                    }
                    Primitive::LineStrip {
                        points,
                        width,
                        color: c,
                    } => out.lines.push(LinePrimitive {
                        r#type: foxglove::messages::line_primitive::Type::LineStrip as i32,
                        pose: pose([0.0; 3], UnitQuaternion::identity()),
                        thickness: *width,
                        scale_invariant: false,
                        points: points.iter().map(|p| point(*p)).collect(),
                        color: color(*c),
                        ..Default::default()
                    }),
                    Primitive::Text {
                        position,
                        text,
                        size,
                        color: c,
                    } => out.texts.push(TextPrimitive {
                        pose: pose(*position, UnitQuaternion::identity()),
                        billboard: true,
                        font_size: *size,
                        scale_invariant: false,
                        color: color(*c),
                        text: text.clone(),
                    }),
                }
            }
            out
        })
        .collect();
    SceneUpdate {
        deletions: vec![SceneEntityDeletion {
            timestamp: Some(ts),
            r#type: scene_entity_deletion::Type::All as i32,
            id: String::new(),
        }],
        entities,
    }
}

/// Every robot link as a child of the root frame (`base_footprint`) at the builder's current
/// joint values, stamped `t_ns`.
pub fn frame_transforms(builder: &SceneBuilder, t_ns: u64) -> FrameTransforms {
    let root = builder.model().root().to_string();
    let ts = timestamp(t_ns);
    FrameTransforms {
        transforms: builder
            .link_poses()
            .into_iter()
            .filter(|(name, _)| *name != root)
            .map(|(name, p)| transform(&root, name, &p, ts))
            .collect(),
    }
}

fn transform(parent: &str, child: &str, p: &Isometry3<f64>, ts: Timestamp) -> FrameTransform {
    let (t, q) = (p.translation.vector, p.rotation);
    FrameTransform {
        timestamp: Some(ts),
        parent_frame_id: parent.to_string(),
        child_frame_id: child.to_string(),
        translation: Some(Vector3 {
            x: t.x,
            y: t.y,
            z: t.z,
        }),
        rotation: Some(Quaternion {
            x: q.i,
            y: q.j,
            z: q.k,
            w: q.w,
        }),
    }
}

fn encode<M: Encode>(m: &M) -> Vec<u8> {
    let mut buf = Vec::with_capacity(m.encoded_len().unwrap_or(1024));
    // Encoding into a growable Vec cannot run out of space.
    let _ = m.encode(&mut buf);
    buf
}

/// How Foxglove files are written.
#[derive(Debug, Clone, PartialEq)]
pub struct FoxgloveOptions {
    /// Most scene (and transform) updates per second of recording time. Default 30.
    pub scene_hz: f64,
    /// Keep the bus's JSON messages on their own channels. Default true.
    pub keep_raw: bool,
    /// How scenes are built.
    pub scene: SceneOptions,
}

impl Default for FoxgloveOptions {
    fn default() -> Self {
        FoxgloveOptions {
            scene_hz: 30.0,
            keep_raw: true,
            scene: SceneOptions::default(),
        }
    }
}

/// What a Foxglove file holds.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FoxgloveSummary {
    /// Bus messages kept as JSON.
    pub raw: u64,
    /// Scene updates written.
    pub scenes: u64,
    /// Transform updates written.
    pub transforms: u64,
    /// Bus messages refused as malformed or invalid (not drawn; kept as JSON all the same).
    pub rejected: u64,
}

/// Writes an MCAP file Foxglove draws in 3D: takes bus messages like echo-record's `Recorder`
/// and adds a scene and the link frames after each scene input, at most `scene_hz` times per
/// second of recording time.
pub struct FoxgloveRecorder<W: Write + Seek> {
    writer: mcap::Writer<W>,
    builder: SceneBuilder,
    opts: FoxgloveOptions,
    raw: HashMap<String, u16>,
    scene_channel: u16,
    tf_channel: u16,
    sequences: HashMap<u16, u32>,
    last_scene: Option<u64>,
    pending: Option<u64>,
    summary: FoxgloveSummary,
}

impl<W: Write + Seek> FoxgloveRecorder<W> {
    /// A recorder writing to `w` (uncompressed chunks, with summary and indexes).
    pub fn new(w: W, opts: &FoxgloveOptions) -> Result<Self, SceneError> {
        if !(opts.scene_hz.is_finite() && opts.scene_hz > 0.0) {
            return Err(SceneError::Option {
                name: "scene_hz",
                message: format!("{} is not a positive rate", opts.scene_hz),
            });
        }
        let mut writer = mcap::WriteOptions::new()
            .compression(None)
            .profile("")
            .library(concat!("echo-scene ", env!("CARGO_PKG_VERSION")))
            .create(w)?;
        let mut channel = |topic: &str, schema: Option<foxglove::Schema>| {
            let schema =
                schema.ok_or_else(|| SceneError::Foxglove(format!("{topic}: no schema")))?;
            let id = writer.add_schema(&schema.name, &schema.encoding, &schema.data)?;
            Ok::<u16, SceneError>(writer.add_channel(id, topic, "protobuf", &BTreeMap::new())?)
        };
        let scene_channel = channel(SCENE_TOPIC, SceneUpdate::get_schema())?;
        let tf_channel = channel(TF_TOPIC, FrameTransforms::get_schema())?;
        let builder =
            SceneBuilder::with_model(echo_robot::RobotModel::tiago_dual(), opts.scene.clone())?;
        Ok(FoxgloveRecorder {
            writer,
            builder,
            opts: opts.clone(),
            raw: HashMap::new(),
            scene_channel,
            tf_channel,
            sequences: HashMap::new(),
            last_scene: None,
            pending: None,
            summary: FoxgloveSummary::default(),
        })
    }

    fn put(
        &mut self,
        channel_id: u16,
        log_time: u64,
        publish_time: u64,
        data: &[u8],
    ) -> Result<(), SceneError> {
        let seq = self.sequences.entry(channel_id).or_insert(0);
        *seq = seq.wrapping_add(1);
        let header = mcap::records::MessageHeader {
            channel_id,
            sequence: *seq,
            log_time,
            publish_time,
        };
        self.writer.write_to_known_channel(&header, data)?;
        Ok(())
    }

    /// Record `payload` received on `key` at `log_time_ns` (and a scene, when one is due).
    pub fn write(&mut self, key: &str, log_time_ns: u64, payload: &[u8]) -> Result<(), SceneError> {
        if self.opts.keep_raw {
            let id = match self.raw.get(key) {
                Some(id) => *id,
                None => {
                    let id = self.writer.add_channel(0, key, "json", &BTreeMap::new())?;
                    self.raw.insert(key.to_string(), id);
                    id
                }
            };
            let publish = sender_stamp(payload).unwrap_or(log_time_ns);
            self.put(id, log_time_ns, publish, payload)?;
            self.summary.raw += 1;
        }
        if self
            .builder
            .on_message_at(key, payload, Some(log_time_ns))
            .is_some()
        {
            let period = (1e9 / self.opts.scene_hz) as u64;
            if self.last_scene.is_none_or(|l| log_time_ns >= l + period) {
                self.write_scene(log_time_ns)?;
            } else {
                self.pending = Some(log_time_ns);
            }
        }
        self.summary.rejected = self.builder.stats().rejected_total();
        Ok(())
    }

    fn write_scene(&mut self, t: u64) -> Result<(), SceneError> {
        let scene = encode(&scene_update(&self.builder.scene(t)));
        let tf = encode(&frame_transforms(&self.builder, t));
        self.put(self.scene_channel, t, t, &scene)?;
        self.put(self.tf_channel, t, t, &tf)?;
        self.summary.scenes += 1;
        self.summary.transforms += 1;
        self.last_scene = Some(t);
        self.pending = None;
        Ok(())
    }

    /// What was written so far.
    pub fn summary(&self) -> &FoxgloveSummary {
        &self.summary
    }

    /// Write the last scene that was due, the summary, and end the file.
    pub fn finish(mut self) -> Result<(W, FoxgloveSummary), SceneError> {
        if let Some(t) = self.pending {
            self.write_scene(t)?;
        }
        self.writer.finish()?;
        Ok((self.writer.into_inner(), self.summary))
    }
}

/// `header.stamp_ns` of a JSON payload, if it has one.
fn sender_stamp(payload: &[u8]) -> Option<u64> {
    serde_json::from_slice::<serde_json::Value>(payload)
        .ok()?
        .pointer("/header/stamp_ns")?
        .as_u64()
}

/// Convert an echo-record MCAP recording into one Foxglove draws in 3D (scenes, link frames and
/// the original JSON messages).
pub fn convert_recording(
    input: &Path,
    output: &Path,
    opts: &FoxgloveOptions,
) -> Result<FoxgloveSummary, SceneError> {
    let records = echo_record::read_recording(input)?;
    let file = std::fs::File::create(output).map_err(|source| SceneError::Io {
        path: output.to_path_buf(),
        source,
    })?;
    let mut rec = FoxgloveRecorder::new(std::io::BufWriter::new(file), opts)?;
    for r in &records {
        rec.write(&r.key, r.log_time_ns, &r.payload)?;
    }
    let (mut w, summary) = rec.finish()?;
    w.flush().map_err(|source| SceneError::Io {
        path: output.to_path_buf(),
        source,
    })?;
    Ok(summary)
}

/// A Foxglove WebSocket server (protocol `foxglove.websocket.v1`) publishing scenes, link
/// frames and, on their key expressions, the bus's JSON messages. Open Foxglove and connect to
/// `ws://localhost:<port>`.
pub struct LiveServer {
    context: Arc<foxglove::Context>,
    handle: foxglove::WebSocketServerHandle,
    scene: foxglove::Channel<SceneUpdate>,
    tf: foxglove::Channel<FrameTransforms>,
    raw: Mutex<HashMap<String, Arc<foxglove::RawChannel>>>,
}

impl LiveServer {
    /// Start serving on `host:port` (port 0: any free port; see [`Self::port`]). Needs a tokio
    /// runtime.
    pub async fn start(host: &str, port: u16) -> Result<LiveServer, SceneError> {
        let context = foxglove::Context::new();
        let scene = context.channel_builder(SCENE_TOPIC).build::<SceneUpdate>();
        let tf = context.channel_builder(TF_TOPIC).build::<FrameTransforms>();
        let handle = foxglove::WebSocketServer::new()
            .name("echo")
            .bind(host, port)
            .context(&context)
            .start()
            .await
            .map_err(|e| {
                SceneError::Foxglove(format!("starting the server on {host}:{port}: {e}"))
            })?;
        Ok(LiveServer {
            context,
            handle,
            scene,
            tf,
            raw: Mutex::new(HashMap::new()),
        })
    }

    /// The port it listens on.
    pub fn port(&self) -> u16 {
        self.handle.port()
    }

    /// Connected clients.
    pub fn clients(&self) -> usize {
        self.handle.client_count()
    }

    /// Publish the builder's scene and link frames at `t_ns`.
    pub fn publish(&self, builder: &SceneBuilder, t_ns: u64) {
        self.scene
            .log_with_time(&scene_update(&builder.scene(t_ns)), t_ns);
        self.tf
            .log_with_time(&frame_transforms(builder, t_ns), t_ns);
    }

    /// Publish a bus message on its key as JSON (the channel is advertised on first use).
    pub fn publish_raw(&self, key: &str, payload: &[u8], t_ns: u64) {
        let mut raw = match self.raw.lock() {
            Ok(g) => g,
            Err(poisoned) => poisoned.into_inner(),
        };
        let channel = match raw.get(key) {
            Some(c) => Some(c.clone()),
            None => self
                .context
                .channel_builder(key)
                .message_encoding("json")
                .build_raw()
                .ok()
                .inspect(|c| {
                    raw.insert(key.to_string(), c.clone());
                }),
        };
        if let Some(c) = channel {
            c.log_with_meta(payload, foxglove::PartialMetadata::with_log_time(t_ns));
        }
    }

    /// Stop serving and wait for the server's tasks to end.
    pub async fn stop(self) {
        self.handle.stop().wait().await;
    }
}
