//! Claims: work one coordinator must do alone (folding a frame or a pass, the retention
//! sweep), held as leases in the store. A claim names its owner (a coordinator's id) and
//! lapses unless renewed, so when the coordinator holding it dies another takes the work over
//! once it lapses; a coordinator that finds its claim lapsed drops what it held in memory.

use super::db::{Optional, params};
use super::{Result, Store};

/// What became of a claim.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Claim {
    /// Held by this owner since before (and renewed).
    Held,
    /// Taken now: it was free, lapsed, or another's that lapsed. What the owner kept in
    /// memory for it may be stale.
    Taken,
    /// Another owner (named) holds it.
    Refused(String),
}

impl Store {
    /// Claims `name` for `owner` until `now + ttl_ms`.
    pub fn claim(&self, name: &str, owner: &str, now: i64, ttl_ms: i64) -> Result<Claim> {
        self.db.write(|tx| {
            let held: Option<(String, i64)> = tx
                .query_row(
                    "SELECT owner, expires_ms FROM claims WHERE name = ?1",
                    params![name],
                    |r| Ok((r.get(0)?, r.get(1)?)),
                )
                .optional()?;
            let outcome = match &held {
                Some((o, expires)) if *expires >= now => {
                    if o == owner {
                        Claim::Held
                    } else {
                        return Ok(Claim::Refused(o.clone()));
                    }
                }
                _ => Claim::Taken,
            };
            tx.execute(
                "INSERT INTO claims (name, owner, expires_ms) VALUES (?1, ?2, ?3)
                 ON CONFLICT (name) DO UPDATE SET owner = excluded.owner,
                    expires_ms = excluded.expires_ms",
                params![name, owner, now + ttl_ms],
            )?;
            Ok(outcome)
        })
    }

    /// Whether `owner` holds `name` (and it has not lapsed).
    pub fn holds(&self, name: &str, owner: &str, now: i64) -> Result<bool> {
        Ok(self
            .conn()?
            .query_row(
                "SELECT 1 FROM claims WHERE name = ?1 AND owner = ?2 AND expires_ms >= ?3",
                params![name, owner, now],
                |_| Ok(()),
            )
            .optional()?
            .is_some())
    }

    /// Renews every claim `owner` holds until `now + ttl_ms`; the names it holds.
    pub fn renew_claims(&self, owner: &str, now: i64, ttl_ms: i64) -> Result<Vec<String>> {
        self.db.write(|tx| {
            tx.execute(
                "UPDATE claims SET expires_ms = ?2 WHERE owner = ?1 AND expires_ms >= ?3",
                params![owner, now + ttl_ms, now],
            )?;
            tx.query_map(
                "SELECT name FROM claims WHERE owner = ?1 AND expires_ms >= ?2 ORDER BY name",
                params![owner, now],
                |r| r.get(0),
            )
        })
    }

    /// Gives up a claim (if `owner` holds it).
    pub fn release(&self, name: &str, owner: &str) -> Result<()> {
        self.conn()?.execute(
            "DELETE FROM claims WHERE name = ?1 AND owner = ?2",
            params![name, owner],
        )?;
        Ok(())
    }

    /// Forgets every claim: for a store only one coordinator uses (the embedded SQLite), at
    /// its start, when the claims left are its own previous run's.
    pub fn forget_claims(&self) -> Result<()> {
        self.conn()?.execute("DELETE FROM claims", params![])?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::store;
    use super::*;

    #[test]
    fn a_claim_is_one_owners_until_it_lapses_or_is_released() {
        let (_d, s, _) = store(&[], 0);
        assert_eq!(s.claim("frame 1/1", "a", 0, 100).expect("a"), Claim::Taken);
        assert_eq!(s.claim("frame 1/1", "a", 50, 100).expect("a"), Claim::Held);
        assert_eq!(
            s.claim("frame 1/1", "b", 60, 100).expect("b"),
            Claim::Refused("a".into())
        );
        assert!(s.holds("frame 1/1", "a", 60).expect("q"));
        assert!(!s.holds("frame 1/1", "b", 60).expect("q"));
        // Renewed at 140: b is refused at 200, takes it once it lapses after 240.
        assert_eq!(
            s.renew_claims("a", 140, 100).expect("renew"),
            vec!["frame 1/1".to_owned()]
        );
        assert_eq!(
            s.claim("frame 1/1", "b", 200, 100).expect("b"),
            Claim::Refused("a".into())
        );
        assert_eq!(
            s.claim("frame 1/1", "b", 241, 100).expect("b"),
            Claim::Taken
        );
        // a finds it lost: renewing keeps nothing, and claiming again is refused.
        assert!(s.renew_claims("a", 250, 100).expect("renew").is_empty());
        assert_eq!(
            s.claim("frame 1/1", "a", 250, 100).expect("a"),
            Claim::Refused("b".into())
        );
        // Released, anyone may take it; releasing another's claim does nothing.
        s.release("frame 1/1", "a").expect("not a's");
        assert!(s.holds("frame 1/1", "b", 250).expect("q"));
        s.release("frame 1/1", "b").expect("release");
        assert_eq!(
            s.claim("frame 1/1", "a", 260, 100).expect("a"),
            Claim::Taken
        );
    }
}
