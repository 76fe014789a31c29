//! HRI training of the forecaster (paper §3.3–3.4, Table 4): the robot is agent B, learned from
//! human–human interactions whose person B was retargeted onto TIAGo++.
//!
//! - [`codec`]: the retargeter's robot encoder/decoder, frozen, around the robot agent (option);
//! - [`data`]: the robot agent's features (17 joints, base, heading) and HRI windows with the
//!   reference person's hands and the proximity weight of the original pair;
//! - [`train`]: movement, interaction and imitation losses through the differentiable FK,
//!   combined as in Eq. 6;
//! - [`eval`]: JPE*, AJPE*, FDE* of the robot against the retargeted reference, F1 of contact
//!   and proximity against the original pair, head rotation error.

pub mod codec;
pub mod data;
pub mod eval;
pub mod train;
