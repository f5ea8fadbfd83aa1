//! Retries: an attempt that fails is tried again after a pause that doubles per attempt up to a
//! cap, or after the server's `Retry-After` (also capped). The caller sees every failed attempt
//! through a hook (the evaluator records them on the episode) and passes the sleep, so tests
//! observe the waits instead of the clock.

use std::time::Duration;

/// Highest power of two the initial pause is multiplied by, so the product cannot overflow
/// (any useful cap is reached long before).
const MAX_DOUBLINGS: u32 = 20;

/// Which failures are tried again.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RetryOn {
    /// Transient failures only ([`Failure::transient`]: connect errors, timeouts, disconnects,
    /// HTTP 408, 429 and 5xx).
    Transient,
    /// Every failure, also those another attempt is unlikely to cure (a 4xx, a reply that
    /// cannot be read): for servers that answer wrongly now and then.
    Any,
}

/// How often and how patiently to try.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RetryPolicy {
    /// Attempts after the first (at most `retries + 1` in all).
    pub retries: u32,
    /// Pause after the first failed attempt; doubled per further failure.
    pub initial: Duration,
    /// Longest pause, `Retry-After` included.
    pub cap: Duration,
    /// Which failures are tried again.
    pub retry_on: RetryOn,
}

/// One failed attempt.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Failure {
    /// What went wrong, as the caller reports it.
    pub message: String,
    /// True when another attempt may cure it.
    pub transient: bool,
    /// The wait the server asked for (`Retry-After`); it replaces the backoff.
    pub retry_after: Option<Duration>,
}

impl Failure {
    /// A transient failure with no wait asked for.
    pub fn new(message: impl Into<String>) -> Failure {
        Failure {
            message: message.into(),
            transient: true,
            retry_after: None,
        }
    }
}

/// Why [`RetryPolicy::run`] gave up.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GaveUp {
    /// Attempts made, all failed.
    pub attempts: u32,
    /// The last attempt's failure.
    pub last: Failure,
}

impl RetryPolicy {
    /// The pause after failed attempt `failed` (0 for the first): `retry_after` when the server
    /// gave one, else `initial × 2^failed`; never more than `cap`.
    pub fn wait(&self, failed: u32, retry_after: Option<Duration>) -> Duration {
        retry_after
            .unwrap_or_else(|| self.initial.saturating_mul(1 << failed.min(MAX_DOUBLINGS)))
            .min(self.cap)
    }

    /// Calls `attempt(n)` for n = 0, 1, … until it succeeds, fails in a way the policy does not
    /// retry, or has failed `retries + 1` times; `on_failure(n, failure)` sees every failure
    /// (the last one too) and `sleep` takes each pause between attempts.
    ///
    /// # Errors
    ///
    /// [`GaveUp`] with the number of attempts and the last failure.
    pub fn run<T>(
        &self,
        mut attempt: impl FnMut(u32) -> Result<T, Failure>,
        mut on_failure: impl FnMut(u32, &Failure),
        mut sleep: impl FnMut(Duration),
    ) -> Result<T, GaveUp> {
        let mut n = 0;
        loop {
            let failure = match attempt(n) {
                Ok(value) => return Ok(value),
                Err(f) => f,
            };
            on_failure(n, &failure);
            let retryable = failure.transient || self.retry_on == RetryOn::Any;
            if n >= self.retries || !retryable {
                return Err(GaveUp {
                    attempts: n + 1,
                    last: failure,
                });
            }
            sleep(self.wait(n, failure.retry_after));
            n += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: Duration = Duration::from_millis(1);

    fn policy(retries: u32, retry_on: RetryOn) -> RetryPolicy {
        RetryPolicy {
            retries,
            initial: 100 * MS,
            cap: 2000 * MS,
            retry_on,
        }
    }

    #[test]
    fn waits_double_up_to_the_cap_and_retry_after_replaces_them() {
        let p = policy(10, RetryOn::Transient);
        let waits: Vec<u128> = (0..7).map(|n| p.wait(n, None).as_millis()).collect();
        assert_eq!(waits, [100, 200, 400, 800, 1600, 2000, 2000]);
        assert_eq!(p.wait(40, None), 2000 * MS);
        assert_eq!(p.wait(3, Some(Duration::ZERO)), Duration::ZERO);
        assert_eq!(p.wait(0, Some(Duration::from_secs(1))), 1000 * MS);
        assert_eq!(p.wait(0, Some(Duration::from_secs(30))), 2000 * MS);
        let huge = RetryPolicy {
            initial: Duration::MAX,
            cap: Duration::MAX,
            ..p
        };
        assert_eq!(huge.wait(20, None), Duration::MAX);
    }

    #[test]
    fn retries_until_success_and_shows_every_failure() {
        let (mut seen, mut slept) = (Vec::new(), Vec::new());
        let got = policy(3, RetryOn::Transient).run(
            |n| {
                if n < 2 {
                    Err(Failure::new(format!("fault {}", n + 1)))
                } else {
                    Ok(n)
                }
            },
            |n, f| seen.push((n, f.message.clone())),
            |d| slept.push(d),
        );
        assert_eq!(got, Ok(2));
        assert_eq!(seen, [(0, "fault 1".into()), (1, "fault 2".into())]);
        assert_eq!(slept, [100 * MS, 200 * MS]);
    }

    #[test]
    fn gives_up_after_the_last_retry_or_at_a_failure_it_does_not_retry() {
        let mut slept = Vec::new();
        let down = policy(1, RetryOn::Transient).run(
            |_| Err::<(), _>(Failure::new("down")),
            |_, _| {},
            |d| slept.push(d),
        );
        assert_eq!(
            down,
            Err(GaveUp {
                attempts: 2,
                last: Failure::new("down")
            })
        );
        assert_eq!(slept, [100 * MS]);

        let bad = Failure {
            transient: false,
            ..Failure::new("HTTP 400")
        };
        let mut calls = 0;
        let once = policy(5, RetryOn::Transient).run(
            |_| {
                calls += 1;
                Err::<(), _>(bad.clone())
            },
            |_, _| {},
            |_| panic!("no pause before giving up"),
        );
        assert_eq!((calls, once.unwrap_err().attempts), (1, 1));
        let mut calls = 0;
        let all = policy(5, RetryOn::Any).run(
            |_| {
                calls += 1;
                Err::<(), _>(bad.clone())
            },
            |_, _| {},
            |_| {},
        );
        assert_eq!((calls, all.unwrap_err().attempts), (6, 6));
    }
}
