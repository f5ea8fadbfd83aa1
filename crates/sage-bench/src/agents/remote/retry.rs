//! Retries of remote requests: a fault (refused, timeout, disconnect, bad framing, an
//! unparseable reply) is retried after a short, growing pause; every fault is kept so the
//! episode's record can show what happened even when a retry made it good.

use std::time::Duration;

/// First pause between attempts; doubled per attempt up to [`BACKOFF_MAX`].
const BACKOFF: Duration = Duration::from_millis(100);
/// Longest pause between attempts.
const BACKOFF_MAX: Duration = Duration::from_secs(2);

/// What the attempts gave: the value of the first that succeeded (`None` when none did) and
/// the faults of those that failed, in order.
#[derive(Debug, Clone, PartialEq)]
pub struct Outcome<T> {
    /// The successful attempt's value.
    pub value: Option<T>,
    /// One message per failed attempt.
    pub faults: Vec<String>,
}

/// Runs `attempt` once and up to `retries` more times while it fails.
pub fn with_retries<T>(retries: u32, mut attempt: impl FnMut() -> Result<T, String>) -> Outcome<T> {
    let mut faults = Vec::new();
    for k in 0..=retries {
        if k > 0 {
            std::thread::sleep(BACKOFF.saturating_mul(1 << (k - 1).min(8)).min(BACKOFF_MAX));
        }
        match attempt() {
            Ok(v) => {
                return Outcome {
                    value: Some(v),
                    faults,
                };
            }
            Err(f) => faults.push(f),
        }
    }
    Outcome {
        value: None,
        faults,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn retries_until_success_and_keeps_every_fault() {
        let mut n = 0;
        let o = with_retries(3, || {
            n += 1;
            if n < 3 {
                Err(format!("fault {n}"))
            } else {
                Ok(n)
            }
        });
        assert_eq!(o.value, Some(3));
        assert_eq!(o.faults, ["fault 1", "fault 2"]);
        let o: Outcome<()> = with_retries(1, || Err("down".into()));
        assert_eq!((o.value, o.faults.len()), (None, 2));
    }
}
