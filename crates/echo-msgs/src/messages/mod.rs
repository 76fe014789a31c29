//! The messages, one module per edge of the data flow.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::skeleton::{COCO17, NUM_JOINTS, SMPL22, SMPL24};
use crate::validate::*;
use crate::{Header, Message, ValidationError};

macro_rules! message {
    ($ty:ty, $kind:literal) => {
        impl Message for $ty {
            const KIND: &'static str = $kind;
            fn header(&self) -> &Header {
                &self.header
            }
            fn header_mut(&mut self) -> &mut Header {
                &mut self.header
            }
        }
    };
}

mod commands;
mod humans;
mod intent;
mod perception;
mod plans;
mod robot;
mod status;

pub use commands::*;
pub use humans::*;
pub use intent::*;
pub use perception::*;
pub use plans::*;
pub use robot::*;
pub use status::*;
