//! CPU renderers shared by everything that renders one scene: a [`RendererPool`] holds as many
//! [`Renderer`]s as have rendered at once, not one per holder. A CPU renderer's memory is
//! mostly its frame buffers (splats, tile lists, per-tile state: about 10 MB at 224×224 and 20
//! MB at 640×480 for a 1M-Gaussian home), so environments that each owned one held a set per
//! environment however few rendered at a time; a vector environment of 64 held 64. Renders
//! beyond the worker threads (a server's request threads) borrow renderers the pool does not
//! keep: it holds at most one per worker thread.

use crate::camera::Camera;
use crate::index::SplatIndex;
use crate::render::{RenderOptions, RenderOutput, RenderStats, Renderer};
use sage_core::Result;
use sage_scene::Gaussians;
use std::sync::{Arc, Mutex, MutexGuard};

/// CPU renderers over one set of Gaussians, lent out one per render: a render takes an idle
/// renderer (or builds one, over the pool's one index, when every one is busy) and gives it
/// back when done. Images do not depend on which renderer formed them: a renderer's buffers
/// carry nothing from one frame to the next.
pub struct RendererPool {
    index: Arc<SplatIndex>,
    count: usize,
    /// The most renderers kept: more renders than worker threads at once only wait on each
    /// other, and a renderer sized for a large frame is hundreds of megabytes.
    keep: usize,
    idle: Mutex<Idle>,
}

/// What the pool's lock guards.
#[derive(Default)]
struct Idle {
    renderers: Vec<Renderer>,
    /// Renderers held, idle or lent (counted once back from their first render: one lost to a
    /// panicking render is not held).
    held: usize,
    /// Timings and counts of the last render to finish.
    last: RenderStats,
}

impl RendererPool {
    /// Indexes `gaussians` for rendering; renderers are built as renders need them and kept up
    /// to one per thread of the current rayon pool.
    pub fn new(gaussians: &Gaussians) -> RendererPool {
        RendererPool {
            index: Arc::new(SplatIndex::build(gaussians)),
            count: gaussians.len(),
            keep: rayon::current_num_threads().max(1),
            idle: Mutex::new(Idle::default()),
        }
    }

    /// How many Gaussians the pool was built for.
    pub fn gaussian_count(&self) -> usize {
        self.count
    }

    /// The spatial index its renderers share.
    pub fn index(&self) -> &SplatIndex {
        &self.index
    }

    /// Timings and counts of the last render to finish (of one camera: the last of its batch).
    pub fn stats(&self) -> RenderStats {
        self.lock().last
    }

    /// Renderers the pool holds: the most renders that were under way at once, up to one per
    /// worker thread, each with buffers sized for the largest frame it rendered.
    pub fn renderers(&self) -> usize {
        self.lock().held
    }

    /// Renders every camera of `cameras` in order, on one renderer of the pool; as
    /// [`Renderer::render`] for each.
    ///
    /// # Errors
    ///
    /// As [`Renderer::render`], for any camera.
    pub fn render_batch(
        &self,
        gaussians: &Gaussians,
        categories: &[u16],
        cameras: &[Camera],
        options: &RenderOptions,
    ) -> Result<Vec<RenderOutput>> {
        let taken = self.lock().renderers.pop();
        let new = taken.is_none();
        // Built and rendering outside the lock: the index is shared, the buffers start empty.
        let mut renderer =
            taken.unwrap_or_else(|| Renderer::with_index(self.index.clone(), self.count));
        let images = cameras
            .iter()
            .map(|c| renderer.render(gaussians, categories, c, options))
            .collect();
        self.give_back(renderer, new);
        images
    }

    /// Takes `renderer` back (`new`: built for the render that returns it), keeping it while
    /// the pool holds fewer than it keeps.
    fn give_back(&self, renderer: Renderer, new: bool) {
        let mut idle = self.lock();
        idle.last = renderer.stats();
        idle.held += usize::from(new);
        if idle.held > self.keep {
            idle.held -= 1;
            // Dropped after the lock: freeing hundreds of megabytes takes a while.
            drop(idle);
            drop(renderer);
        } else {
            idle.renderers.push(renderer);
        }
    }

    fn lock(&self) -> MutexGuard<'_, Idle> {
        // The lock is held only to push, pop or count, which leave `Idle` whole even if a
        // panic poisoned it in between.
        self.idle.lock().unwrap_or_else(|e| e.into_inner())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Intrinsics;
    use rayon::prelude::*;
    use sage_scene::Gaussian;

    fn scene() -> Gaussians {
        let mut g = Gaussians::new(1).unwrap();
        for i in 0..2_000 {
            let t = i as f32 * 0.37;
            g.push(&Gaussian {
                position: glam::Vec3::new(t.sin() * 2.0, 3.0 + (t * 0.7).cos(), (t * 1.3).sin()),
                log_scale: glam::Vec3::new(-3.0, -3.2, -2.8),
                opacity_logit: 1.5,
                sh_dc: [0.4 * t.cos(), 0.2, -0.1],
                instance: 1 + i % 5,
                ..Gaussian::default()
            });
        }
        g
    }

    fn cameras(n: usize) -> Vec<Camera> {
        let k = Intrinsics::from_hfov(48, 40, 90.0).unwrap();
        (0..n)
            .map(|i| {
                Camera::from_yaw_pitch(
                    k,
                    glam::Vec3::new(0.1 * i as f32, -1.0, 0.2),
                    std::f32::consts::FRAC_PI_2 + 0.05 * i as f32,
                    0.0,
                )
            })
            .collect()
    }

    #[test]
    fn lent_renderers_form_the_images_of_one_renderer_of_their_own() {
        let g = scene();
        let cams = cameras(12);
        let options = RenderOptions::default();
        let categories = [0, 3, 4, 5, 6, 7];
        let alone: Vec<RenderOutput> = cams
            .iter()
            .map(|c| {
                Renderer::new(&g)
                    .render(&g, &categories, c, &options)
                    .unwrap()
            })
            .collect();
        assert!(alone.iter().any(|o| o.alpha.iter().any(|&a| a > 0.5)));
        let pool = RendererPool::new(&g);
        // From many threads at once, each camera twice: whichever renderer is lent, and
        // whatever it rendered before, the bytes are those of a fresh renderer.
        let shared: Vec<RenderOutput> = (0..cams.len() * 2)
            .into_par_iter()
            .map(|i| {
                let c = &cams[i % cams.len()];
                pool.render_batch(&g, &categories, std::slice::from_ref(c), &options)
                    .unwrap()
                    .remove(0)
            })
            .collect();
        for (i, out) in shared.iter().enumerate() {
            assert_eq!(out, &alone[i % cams.len()], "camera {i}");
        }
        assert!((1..=rayon::current_num_threads()).contains(&pool.renderers()));
    }

    #[test]
    fn one_renderer_lent_for_frames_of_every_size_forms_fresh_images() {
        let g = scene();
        let pool = RendererPool::new(&g);
        let options = RenderOptions::default();
        let eye = glam::Vec3::new(0.0, -1.0, 0.2);
        // Growing, shrinking and odd sizes through one renderer: its buffers, sized by the
        // frames before, must not show in the next.
        let mut seen = 0;
        for (i, (w, h)) in [(64, 48), (17, 95), (200, 120), (33, 31), (96, 64), (16, 16)]
            .into_iter()
            .enumerate()
        {
            let k = Intrinsics::from_hfov(w, h, 80.0 + 5.0 * i as f32).unwrap();
            let c = Camera::from_yaw_pitch(k, eye, std::f32::consts::FRAC_PI_2, 0.1);
            let lent = pool
                .render_batch(&g, &[], &[c], &options)
                .unwrap()
                .remove(0);
            let fresh = Renderer::new(&g).render(&g, &[], &c, &options).unwrap();
            assert_eq!((lent.width, lent.height), (w as usize, h as usize));
            assert_eq!(lent, fresh, "{w}x{h}");
            seen += usize::from(lent.alpha.iter().any(|&a| a > 0.5));
        }
        assert!(seen >= 4, "{seen} frames saw the Gaussians");
        assert_eq!(pool.renderers(), 1);
    }

    #[test]
    fn renders_one_after_another_share_one_renderer() {
        let g = scene();
        let pool = RendererPool::new(&g);
        let options = RenderOptions::default();
        for c in cameras(5) {
            pool.render_batch(&g, &[], &[c], &options).unwrap();
        }
        assert_eq!(pool.renderers(), 1);
        assert!(pool.stats().splats > 0);
        let batch = pool.render_batch(&g, &[], &cameras(3), &options).unwrap();
        assert_eq!(batch.len(), 3);
        assert_eq!(pool.renderers(), 1);
    }

    #[test]
    fn renderers_beyond_one_per_worker_thread_are_not_kept() {
        let g = scene();
        let pool = RendererPool::new(&g);
        let keep = rayon::current_num_threads();
        // As many renders at once as a server's request threads may start: each built its own.
        for _ in 0..keep + 5 {
            pool.give_back(Renderer::with_index(pool.index.clone(), pool.count), true);
        }
        assert_eq!(pool.renderers(), keep);
        assert_eq!(pool.lock().renderers.len(), keep);
        // The kept ones are lent again, and a render that finds none idle builds one.
        let busy: Vec<Renderer> = (0..keep)
            .map(|_| pool.lock().renderers.pop().unwrap())
            .collect();
        pool.render_batch(&g, &[], &cameras(1), &RenderOptions::default())
            .unwrap();
        assert_eq!(pool.renderers(), keep, "the extra one is dropped");
        for r in busy {
            pool.give_back(r, false);
        }
        assert_eq!(pool.lock().renderers.len(), keep);
    }

    #[test]
    fn another_set_of_gaussians_is_refused() {
        let g = scene();
        let pool = RendererPool::new(&g);
        let e = pool
            .render_batch(
                &Gaussians::default(),
                &[],
                &cameras(1),
                &RenderOptions::default(),
            )
            .unwrap_err();
        assert!(
            e.message()
                .contains("renderer was built for 2000 Gaussians"),
            "{e}"
        );
        // The renderer that refused is back in the pool.
        assert_eq!(pool.renderers(), 1);
        assert!(
            pool.render_batch(&g, &[], &cameras(1), &RenderOptions::default())
                .is_ok()
        );
        assert_eq!(pool.renderers(), 1);
    }
}
