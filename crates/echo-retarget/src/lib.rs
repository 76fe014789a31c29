//! Human-to-robot retargeting for TIAGo++.

pub mod fk;
