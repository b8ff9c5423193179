//! The binary encoding of moment statistics (a `.dynm` file): an 8-byte magic `DYNIDMOM`,
//! the format version (u32, little-endian), the payload's length (u64, little-endian), the
//! payload — the statistics in `postcard`'s encoding, every `f64` as its 8 bytes
//! (little-endian: exact), integers as varints — and the payload's FNV-1a hash (u64,
//! little-endian), which catches a change of any byte.

use super::{fnv1a, MomentStats, MomentsError};

/// The first bytes of every moment statistics file.
pub const MAGIC: &[u8; 8] = b"DYNIDMOM";
/// The format version written, and the only one read.
pub const FORMAT_VERSION: u32 = 1;
/// Bytes before the payload: magic, version, length.
const HEADER: usize = 8 + 4 + 8;

impl MomentStats {
    /// The statistics as the bytes of a `.dynm` file.
    pub fn to_bytes(&self) -> Vec<u8> {
        let payload = postcard::to_allocvec(self)
            .expect("invariant: every field of the statistics has a serde encoding");
        let mut out = Vec::with_capacity(HEADER + payload.len() + 8);
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
        out.extend_from_slice(&payload);
        out.extend_from_slice(&fnv1a(&payload).to_le_bytes());
        out
    }

    /// Read the bytes of a `.dynm` file (`origin` names it in errors): refused unless it
    /// has the header, this format version, its whole length and an intact payload.
    pub fn from_bytes(bytes: &[u8], origin: &str) -> Result<MomentStats, MomentsError> {
        let origin = origin.to_string();
        if bytes.len() < MAGIC.len() || &bytes[..MAGIC.len()] != MAGIC {
            return Err(MomentsError::NotMoments { origin });
        }
        if bytes.len() < HEADER {
            return Err(MomentsError::Truncated {
                origin,
                have: bytes.len(),
                need: HEADER,
            });
        }
        let word = |at: usize, n: usize| -> u64 {
            bytes[at..at + n]
                .iter()
                .rev()
                .fold(0u64, |acc, b| (acc << 8) | u64::from(*b))
        };
        let version = word(8, 4) as u32;
        if version != FORMAT_VERSION {
            return Err(MomentsError::Version {
                origin,
                found: version,
                supported: FORMAT_VERSION,
            });
        }
        let len = word(12, 8);
        let need = usize::try_from(len)
            .ok()
            .and_then(|l| l.checked_add(HEADER + 8))
            .ok_or_else(|| MomentsError::Corrupt {
                origin: origin.clone(),
                detail: format!("a payload length of {len} bytes"),
            })?;
        if bytes.len() < need {
            return Err(MomentsError::Truncated {
                origin,
                have: bytes.len(),
                need,
            });
        }
        if bytes.len() > need {
            return Err(MomentsError::Corrupt {
                origin,
                detail: format!("{} bytes after the end", bytes.len() - need),
            });
        }
        let payload = &bytes[HEADER..need - 8];
        if fnv1a(payload) != word(need - 8, 8) {
            return Err(MomentsError::Corrupt {
                origin,
                detail: "the payload does not match its checksum".into(),
            });
        }
        let stats: MomentStats =
            postcard::from_bytes(payload).map_err(|e| MomentsError::Corrupt {
                origin: origin.clone(),
                detail: format!("cannot decode the payload: {e}"),
            })?;
        stats
            .check_shapes()
            .map_err(|detail| MomentsError::Corrupt { origin, detail })?;
        Ok(stats)
    }

    /// Whether the decoded statistics are consistent (every level's moments of the same
    /// shape, as many boundaries as blocks plus one): a payload with the right checksum
    /// but wrong shapes was not written by this format.
    fn check_shapes(&self) -> Result<(), String> {
        if self.levels.is_empty() {
            return Err("no level".into());
        }
        let first = &self.levels[0].moments;
        for (i, l) in self.levels.iter().enumerate() {
            let m = &l.moments;
            let blocks = m.lens.len();
            let (ni, nw, nq) = (m.n_row_signals, m.n_col_signals, m.n_snap_cols);
            let ok = (ni, nw, nq) == (first.n_row_signals, first.n_col_signals, first.n_snap_cols)
                && m.sums.len() == blocks
                && m.tsums.len() == blocks
                && m.kept.len() == blocks
                && m.snaps.len() == blocks + 1
                && m.sums.iter().chain(&m.tsums).all(|s| s.len() == ni * nw)
                && m.snaps.iter().all(|s| s.len() == ni * nq)
                && m.ts.is_finite()
                && m.ts > 0.0;
            if !ok {
                return Err(format!("level {} has moments of inconsistent shape", i + 1));
            }
        }
        Ok(())
    }
}
