//! Episode animations for the player's download (`video.gif`): each made once, one at a time,
//! and the latest [`KEPT`] kept. An animation takes seconds of rendering; made this way, one
//! whose client gave up still serves the next request for it, and a burst of requests waits on
//! one render instead of starting a burst of them.

use sage_core::{Error, Result};
use std::collections::VecDeque;
use std::sync::{Arc, Mutex, OnceLock};

/// How many animations are kept (a few megabytes each).
pub const KEPT: usize = 16;

/// An animation's making, done once: the GIF, or why it could not be made.
type Made = Arc<OnceLock<std::result::Result<Arc<Vec<u8>>, String>>>;

/// The animations made so far, oldest first.
#[derive(Default)]
pub struct VideoCache {
    made: Mutex<VecDeque<(String, Made)>>,
    /// Held while an animation is made.
    making: Mutex<()>,
}

impl VideoCache {
    /// The animation of episode `id`, made by `make` unless it is kept (requests for one being
    /// made wait for it; requests for another wait their turn).
    ///
    /// # Errors
    ///
    /// What `make` returned (kept too: making it again would fail again).
    pub fn get(&self, id: &str, make: impl FnOnce() -> Result<Vec<u8>>) -> Result<Arc<Vec<u8>>> {
        let cell = {
            let mut made = self.made.lock().unwrap_or_else(|e| e.into_inner());
            match made.iter().find(|(k, _)| k == id) {
                Some((_, cell)) => cell.clone(),
                None => {
                    let cell = Made::default();
                    made.push_back((id.to_string(), cell.clone()));
                    if made.len() > KEPT {
                        made.pop_front();
                    }
                    cell
                }
            }
        };
        cell.get_or_init(|| {
            let _one = self.making.lock().unwrap_or_else(|e| e.into_inner());
            make().map(Arc::new).map_err(|e| e.to_string())
        })
        .clone()
        .map_err(Error::invalid)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};

    #[test]
    fn each_animation_is_made_once_and_the_oldest_are_let_go() {
        let cache = VideoCache::default();
        let makes = AtomicUsize::new(0);
        let make = |id: &str| {
            let id = id.to_string();
            let makes = &makes;
            move || {
                makes.fetch_add(1, Ordering::SeqCst);
                Ok(id.into_bytes())
            }
        };
        // Eight requests at once for one episode: one making.
        std::thread::scope(|s| {
            for _ in 0..8 {
                s.spawn(|| assert_eq!(*cache.get("e0", make("e0")).unwrap(), b"e0"));
            }
        });
        assert_eq!(makes.load(Ordering::SeqCst), 1);
        for i in 1..=KEPT {
            let id = format!("e{i}");
            assert_eq!(*cache.get(&id, make(&id)).unwrap(), id.as_bytes());
        }
        assert_eq!(makes.load(Ordering::SeqCst), KEPT + 1);
        // e0 was let go when the seventeenth came; the latest is kept.
        cache.get("e0", make("e0")).unwrap();
        cache.get(&format!("e{KEPT}"), make("x")).unwrap();
        assert_eq!(makes.load(Ordering::SeqCst), KEPT + 2);
        // A failure is an answer too.
        let failed = || Err(Error::invalid("the scene is gone"));
        assert!(cache.get("bad", failed).is_err());
        let e = cache.get("bad", make("bad")).unwrap_err();
        assert!(e.to_string().contains("the scene is gone"), "{e}");
    }
}
