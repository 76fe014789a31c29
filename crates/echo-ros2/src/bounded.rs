//! Decoding of CDR strings and byte sequences that never trusts a length field.
//!
//! The `cdr` crate (0.2.4) reads a string or a `sequence<uint8>` by allocating and zeroing
//! the declared length before checking it against the sample: a 70-byte sample that declares
//! 4 GiB makes it allocate 4 GiB. These functions read the same wire layout (a `u32` length,
//! then that many bytes; a string's include its NUL) element by element through the
//! deserializer's sequence access, so a forged length fails at the end of the sample after at
//! most as many bytes as the sample holds. Encoding is unchanged (serde's defaults).

use serde::de::{Deserializer, SeqAccess, Visitor};

/// Most bytes reserved up front for one sequence; beyond, the vector grows as bytes arrive.
const RESERVE: usize = 1 << 16;

struct Bytes;

impl<'de> Visitor<'de> for Bytes {
    type Value = Vec<u8>;
    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a CDR byte sequence")
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut a: A) -> Result<Vec<u8>, A::Error> {
        let mut out = Vec::with_capacity(a.size_hint().unwrap_or(0).min(RESERVE));
        while let Some(b) = a.next_element::<u8>()? {
            out.push(b);
        }
        Ok(out)
    }
}

/// `sequence<uint8>`.
pub fn bytes<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<u8>, D::Error> {
    d.deserialize_seq(Bytes)
}

/// A CDR string: its bytes up to the NUL, UTF-8.
pub fn string<'de, D: Deserializer<'de>>(d: D) -> Result<String, D::Error> {
    let mut b = d.deserialize_seq(Bytes)?;
    if b.last() == Some(&0) {
        b.pop();
    }
    String::from_utf8(b).map_err(serde::de::Error::custom)
}

struct Str(String);

impl<'de> serde::Deserialize<'de> for Str {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        string(d).map(Str)
    }
}

struct Strings;

impl<'de> Visitor<'de> for Strings {
    type Value = Vec<String>;
    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a CDR sequence of strings")
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut a: A) -> Result<Vec<String>, A::Error> {
        let mut out = Vec::with_capacity(a.size_hint().unwrap_or(0).min(1024));
        while let Some(Str(s)) = a.next_element::<Str>()? {
            out.push(s);
        }
        Ok(out)
    }
}

/// `sequence<string>`.
pub fn strings<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<String>, D::Error> {
    d.deserialize_seq(Strings)
}
