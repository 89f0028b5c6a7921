//! A part of the work, `I/N`: the chunks `c` with `c mod N == I`, one task of an array job.

/// A part of the work: chunks `c` with `c mod count == index`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// This part, from 0.
    pub index: u64,
    /// How many parts.
    pub count: u64,
}

impl Shard {
    /// The whole dataset.
    pub const WHOLE: Shard = Shard { index: 0, count: 1 };

    /// A checked shard.
    pub fn new(index: u64, count: u64) -> std::result::Result<Shard, String> {
        if count == 0 {
            return Err(format!("shard {index}/{count}: N must be at least 1"));
        }
        if index >= count {
            return Err(format!(
                "shard {index}/{count}: I must be below N (shards are numbered 0 to {})",
                count - 1
            ));
        }
        Ok(Shard { index, count })
    }

    /// The chunks of this shard among `chunks`.
    pub fn chunks(&self, chunks: u64) -> impl Iterator<Item = u64> + use<> {
        (self.index..chunks).step_by(self.count as usize)
    }
}

impl std::str::FromStr for Shard {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let bad = || format!("shard '{s}' is not I/N (e.g. 0/4)");
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let i: u64 = i.trim().parse().map_err(|_| bad())?;
        let n: u64 = n.trim().parse().map_err(|_| bad())?;
        Shard::new(i, n)
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}
