//! What machine a figure was measured on, and how much memory the process holds.

/// The CPU model, the cores visible and the worker threads used, e.g.
/// `"AMD EPYC 7B13, 2 cores visible, 2 threads used"`.
pub fn describe() -> String {
    let model = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_string())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_string());
    format!(
        "{model}, {} cores visible, {} threads used",
        std::thread::available_parallelism().map_or(1, |n| n.get()),
        rayon::current_num_threads()
    )
}

/// Resident set size of this process in bytes (Linux), if known.
pub fn resident_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}
