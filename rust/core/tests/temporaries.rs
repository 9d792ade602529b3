//! A process told to stop (the CLI's SIGINT/SIGTERM handler) removes the temporary files of the
//! writes it will not finish: [`remove_temporaries`] removes them and leaves every destination as
//! it was. Alone in its own test binary, since it acts on every write of the process.

use std::io::Write;

use hairrecon_core::formats::{atomic_write, is_temporary, remove_temporaries};

#[test]
fn the_temporaries_of_unfinished_writes_are_removed() {
    let dir = std::env::temp_dir().join(format!("hairrecon-temporaries-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("out.bin");
    std::fs::write(&path, b"old").unwrap();
    let names = || -> Vec<String> {
        std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect()
    };
    let e = atomic_write(&path, |w| {
        w.write_all(b"never")?;
        w.flush()?;
        assert!(names().iter().any(|n| is_temporary(n)), "{:?}", names());
        // What the signal handler does while this write runs on another thread.
        assert_eq!(remove_temporaries(), 1);
        assert_eq!(names(), ["out.bin"]);
        Ok(())
    });
    assert!(e.is_err(), "the rename of a removed temporary must fail");
    assert_eq!(std::fs::read(&path).unwrap(), b"old");
    assert_eq!(names(), ["out.bin"]);
    assert_eq!(remove_temporaries(), 0, "a finished write is no longer listed");
    std::fs::remove_dir_all(&dir).unwrap();
}
