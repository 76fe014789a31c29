//! The scene description: entities made of primitives, in the robot's base frame.

use serde::{Deserialize, Serialize};

/// A colour with straight (not premultiplied) alpha, each channel in [0, 1].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Rgba {
    /// Red.
    pub r: f32,
    /// Green.
    pub g: f32,
    /// Blue.
    pub b: f32,
    /// Opacity (1 = opaque).
    pub a: f32,
}

impl Rgba {
    /// An opaque colour from 8-bit channels.
    pub const fn rgb8(r: u8, g: u8, b: u8) -> Rgba {
        Rgba {
            r: r as f32 / 255.0,
            g: g as f32 / 255.0,
            b: b as f32 / 255.0,
            a: 1.0,
        }
    }

    /// The same colour with opacity `a`.
    pub const fn with_alpha(self, a: f32) -> Rgba {
        Rgba { a, ..self }
    }

    /// 8-bit red, green, blue.
    pub fn to_rgb8(self) -> [u8; 3] {
        let c = |x: f32| (x.clamp(0.0, 1.0) * 255.0).round() as u8;
        [c(self.r), c(self.g), c(self.b)]
    }
}

/// One drawable shape. Points are `[x, y, z]` in metres in the scene's frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Primitive {
    /// A ball.
    Sphere {
        /// Centre.
        centre: [f64; 3],
        /// Radius, m.
        radius: f64,
        /// Colour.
        color: Rgba,
    },
    /// A cylinder from `a` to `b` with hemispherical ends (a sphere when `a == b`).
    Capsule {
        /// One end of the axis.
        a: [f64; 3],
        /// The other end.
        b: [f64; 3],
        /// Radius, m.
        radius: f64,
        /// Colour.
        color: Rgba,
    },
    /// Connected segments `p0–p1, p1–p2, …`.
    LineStrip {
        /// The points (at least two to draw anything).
        points: Vec<[f64; 3]>,
        /// Line width, m.
        width: f64,
        /// Colour.
        color: Rgba,
    },
    /// A label that always faces the viewer.
    Text {
        /// Anchor (the centre of the text box).
        position: [f64; 3],
        /// The text.
        text: String,
        /// Height of a line, m.
        size: f64,
        /// Colour.
        color: Rgba,
    },
}

/// What an entity shows; viewers may style or filter by it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EntityKind {
    /// The interaction partner, as seen now.
    Partner,
    /// Anybody else who is tracked.
    Person,
    /// The partner's forecast future (a fading ghost).
    Forecast,
    /// The robot's forecast plan (a fading ghost of its gripper paths).
    RobotPlan,
    /// The robot's collision capsules at the measured joint state.
    Robot,
    /// The head camera's field of view.
    Camera,
    /// The closest robot–person distance, as a line between the two closest points.
    Separation,
    /// The safety filter's state.
    Safety,
}

/// A named group of primitives; an entity with the same `id` in a later scene replaces it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Entity {
    /// Stable identifier, e.g. `person/3`, `robot`, `forecast/3`.
    pub id: String,
    /// What it shows.
    pub kind: EntityKind,
    /// Its shapes.
    pub primitives: Vec<Primitive>,
}

/// One line of text for a viewer's 2D overlay.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Caption {
    /// The text.
    pub text: String,
    /// Its colour.
    pub color: Rgba,
}

/// Everything to draw at one instant, in the robot's base frame ([`Scene::frame_id`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Scene {
    /// The instant, ns since the Unix epoch.
    pub time_ns: u64,
    /// The frame every point is expressed in (`base_footprint`).
    pub frame_id: String,
    /// Lines for a 2D overlay (the safety state first, then the announced interaction).
    pub captions: Vec<Caption>,
    /// The entities.
    pub entities: Vec<Entity>,
}

impl Scene {
    /// The first entity with `id`.
    pub fn entity(&self, id: &str) -> Option<&Entity> {
        self.entities.iter().find(|e| e.id == id)
    }

    /// Entities of one kind.
    pub fn of_kind(&self, kind: EntityKind) -> impl Iterator<Item = &Entity> {
        self.entities.iter().filter(move |e| e.kind == kind)
    }
}
