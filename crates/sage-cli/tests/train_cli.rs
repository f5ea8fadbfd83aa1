//! `sage3d bench fit`: a tiny fit reports PSNR before and after and the time per iteration.

mod common;

use common::ok;

#[test]
fn bench_fit_reports_psnr_and_time_per_iteration() {
    let out = ok(&[
        "bench",
        "fit",
        "--iterations",
        "3",
        "--size",
        "24x18",
        "--gaussians",
        "2000",
        "--views",
        "2",
        "--heldout",
        "1",
    ]);
    assert!(out.contains("machine"), "{out}");
    assert!(
        out.contains("held-out PSNR") && out.contains(" dB ->"),
        "{out}"
    );
    assert!(
        out.contains("3 iterations") && out.contains("ms per iteration"),
        "{out}"
    );
}
