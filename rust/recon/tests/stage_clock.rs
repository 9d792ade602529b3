//! The CPU time a run's report gives each stage (`report::StageClock`), in a process of its own so
//! that no other test's threads add theirs: busy work counts, waiting does not.

#[cfg(target_os = "linux")]
#[test]
fn a_stage_clock_counts_cpu_time_not_waiting() {
    use hairrecon_recon::report::StageClock;
    let clock = StageClock::start();
    let t = std::time::Instant::now();
    let mut x = 1u64;
    // Busy until the clock has counted 0.4 s of CPU (on a loaded machine that takes longer than
    // 0.4 s of wall time); a clock that counts nothing never gets there.
    while clock.elapsed().1.expect("/proc/self/stat reads on Linux") < 0.4 {
        assert!(t.elapsed().as_secs_f64() < 20.0, "20 s of busy work and the clock counted under 0.4 s");
        for _ in 0..100_000 {
            x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(1));
        }
    }
    std::thread::sleep(std::time::Duration::from_millis(400));
    let (wall, cpu) = clock.elapsed();
    let cpu = cpu.expect("/proc/self/stat reads on Linux");
    // The busy part took at least 0.4 s of CPU as counted in 10 ms ticks (so at least about 0.38 s
    // of wall time), the sleep at least 0.4 s.
    assert!(wall >= 0.75, "wall {wall} s");
    // 0.4 s of work, not the 0.4 s asleep on top (ticks are 10 ms).
    assert!((0.4..=0.55).contains(&cpu), "cpu {cpu} s of wall {wall} s");
}
