//! Image I/O round trips and errors: PNG 8/16-bit and OpenEXR float, gray and RGB.

use std::path::PathBuf;

use hairrecon_core::formats::FormatErrorKind;
use hairrecon_core::image_io::*;

fn tmp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("hairrecon-image-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A seeded xorshift generator for test data.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn f32(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
}

#[test]
fn png_round_trips_quantise_exactly() {
    let d = tmp_dir("png");
    let (w, h) = (7, 5);
    // Values on the 8-bit grid read back exactly; others within half a step.
    let grid: Vec<f32> = (0..w * h).map(|i| ((i * 37) % 256) as f32 / 255.0).collect();
    let g = GrayImage32::new(w, h, grid.clone()).unwrap();
    write_png8_gray(d.join("g8.png"), &g).unwrap();
    assert_eq!(read_gray_f32(d.join("g8.png")).unwrap(), g);
    let mut rng = Rng(7);
    let any: Vec<f32> = (0..w * h).map(|_| rng.f32()).collect();
    let g = GrayImage32::new(w, h, any.clone()).unwrap();
    write_png16_gray(d.join("g16.png"), &g).unwrap();
    let back = read_gray_f32(d.join("g16.png")).unwrap();
    for (a, b) in any.iter().zip(&back.data) {
        assert!((a - b).abs() <= 0.5 / 65535.0 + 1e-7, "{a} {b}");
    }
    // Out-of-range values are clamped.
    let g = GrayImage32::new(2, 1, vec![-3.0, 7.0]).unwrap();
    write_png8_gray(d.join("clamp.png"), &g).unwrap();
    assert_eq!(read_gray_f32(d.join("clamp.png")).unwrap().data, vec![0.0, 1.0]);
    // RGB: exact on the grid; the gray reader gives Rec. 709 luminance.
    let rgb: Vec<f32> = (0..3 * w * h).map(|i| ((i * 11) % 256) as f32 / 255.0).collect();
    let c = RgbImage32::new(w, h, rgb.clone()).unwrap();
    write_png8_rgb(d.join("c8.png"), &c).unwrap();
    assert_eq!(read_rgb_f32(d.join("c8.png")).unwrap(), c);
    let y = read_gray_f32(d.join("c8.png")).unwrap();
    let [r, g_, b] = c.get(3, 2);
    assert!((y.get(3, 2) - (0.2126 * r + 0.7152 * g_ + 0.0722 * b)).abs() < 1e-4);
    // A gray PNG read as RGB repeats the gray value.
    let c = read_rgb_f32(d.join("g8.png")).unwrap();
    assert_eq!(c.get(4, 3), [grid[3 * 7 + 4]; 3]);
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn exr_round_trips_are_bit_exact() {
    let d = tmp_dir("exr");
    let mut rng = Rng(11);
    let (w, h) = (9, 4);
    let vals: Vec<f32> = (0..w * h).map(|_| (rng.f32() - 0.5) * 1e4).collect();
    let g = GrayImage32::new(w, h, vals).unwrap();
    write_exr_gray_f32(d.join("g.exr"), &g).unwrap();
    assert_eq!(read_gray_f32(d.join("g.exr")).unwrap(), g);
    assert_eq!(read_exr_channel(d.join("g.exr"), "Y").unwrap(), g);
    let e = read_exr_channel(d.join("g.exr"), "Z").unwrap_err();
    assert!(e.to_string().contains("no channel \"Z\"") && e.to_string().contains("g.exr"), "{e}");
    let c = read_rgb_f32(d.join("g.exr")).unwrap();
    assert_eq!(c.get(5, 2), [g.get(5, 2); 3]);

    let vals: Vec<f32> = (0..3 * w * h).map(|_| rng.f32() * 3.0 - 1.0).collect();
    let c = RgbImage32::new(w, h, vals).unwrap();
    write_exr_rgb_f32(d.join("c.exr"), &c).unwrap();
    assert_eq!(read_rgb_f32(d.join("c.exr")).unwrap(), c);
    // Gray from an RGB EXR is the R channel, not a mix of data channels.
    let r = read_gray_f32(d.join("c.exr")).unwrap();
    assert_eq!(r.get(8, 3), c.get(8, 3)[0]);
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn errors_name_the_file_and_leave_no_output() {
    let d = tmp_dir("err");
    // Wrong size.
    assert!(GrayImage32::new(3, 3, vec![0.0; 8]).is_err());
    assert!(RgbImage32::new(0, 3, vec![]).is_err());
    // NaN cannot go to PNG: an error naming the file, and no file left behind.
    let g = GrayImage32::new(2, 2, vec![0.0, f32::NAN, 0.5, 1.0]).unwrap();
    let p = d.join("nan.png");
    let e = write_png8_gray(&p, &g).unwrap_err();
    assert_eq!(e.path.as_deref(), Some(p.as_path()));
    assert!(e.to_string().contains("NaN"), "{e}");
    assert_eq!(std::fs::read_dir(&d).unwrap().count(), 0);
    // Not an image.
    std::fs::write(d.join("x.png"), b"hello world").unwrap();
    let e = read_gray_f32(d.join("x.png")).unwrap_err();
    assert!(matches!(e.kind, FormatErrorKind::BadMagic { .. }) && e.to_string().contains("x.png"), "{e}");
    // Truncated PNG and EXR files: errors, never panics.
    write_png8_gray(d.join("ok.png"), &GrayImage32::filled(16, 16, 0.5)).unwrap();
    write_exr_gray_f32(d.join("ok.exr"), &GrayImage32::filled(16, 16, 0.5)).unwrap();
    for name in ["ok.png", "ok.exr"] {
        let bytes = std::fs::read(d.join(name)).unwrap();
        // (A PNG cut inside its final IEND chunk still holds every pixel and decodes; cut earlier.)
        for cut in [8, bytes.len() / 2, bytes.len() - 13] {
            assert!(read_gray_f32_bytes(&bytes[..cut]).is_err(), "{name} cut at {cut}");
        }
    }
    // Missing file.
    let e = read_rgb_f32(d.join("missing.exr")).unwrap_err();
    assert!(matches!(e.kind, FormatErrorKind::Io(_)) && e.to_string().contains("missing.exr"), "{e}");
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn corrupt_png_and_exr_files_give_errors_not_panics() {
    let d = tmp_dir("fuzz");
    let mut rng = Rng(99);
    let vals: Vec<f32> = (0..16 * 12).map(|_| rng.f32()).collect();
    let g = GrayImage32::new(16, 12, vals).unwrap();
    write_png16_gray(d.join("a.png"), &g).unwrap();
    write_exr_gray_f32(d.join("a.exr"), &g).unwrap();
    for name in ["a.png", "a.exr"] {
        let valid = std::fs::read(d.join(name)).unwrap();
        let (mut ok, mut err) = (0, 0);
        for case in 0..2_000 {
            let mut b = valid.clone();
            match rng.next() % 3 {
                0 => {
                    for _ in 0..1 + rng.next() % 4 {
                        let i = (rng.next() % b.len() as u64) as usize;
                        b[i] = rng.next() as u8;
                    }
                }
                1 => b.truncate((rng.next() % b.len() as u64) as usize),
                _ => {
                    let at = (rng.next() % b.len() as u64) as usize;
                    b.insert(at, rng.next() as u8);
                }
            }
            let r =
                std::panic::catch_unwind(|| (read_gray_f32_bytes(&b).map(|_| ()), read_rgb_f32_bytes(&b).map(|_| ())));
            match r {
                Ok((Ok(()), Ok(()))) => ok += 1,
                Ok(_) => err += 1,
                Err(_) => panic!("{name}: case {case} panicked"),
            }
        }
        println!("{name}: 2000 corruptions, {ok} read, {err} rejected");
        assert!(err > 500, "{name}: {err}");
    }
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn raw_images_keep_their_samples_and_channels() {
    let d = tmp_dir("raw");
    let (w, h) = (5u32, 3u32);
    let n = (w * h) as usize;
    for c in 1..=4usize {
        // Every sample distinct and asymmetric in x and y: a transposed or flipped image fails.
        let s8: Vec<u8> = (0..n * c).map(|i| (i * 7 % 251) as u8).collect();
        let img = RawImage::new(w, h, c, Samples::U8(s8)).unwrap();
        let p = d.join(format!("u8_{c}.png"));
        write_image(&p, &img, None).unwrap();
        assert_eq!(read_image(&p).unwrap(), img, "8-bit, {c} channel(s)");
        let s16: Vec<u16> = (0..n * c).map(|i| (i as u16).wrapping_mul(4099) ^ 0x8001).collect();
        let img = RawImage::new(w, h, c, Samples::U16(s16)).unwrap();
        let p = d.join(format!("u16_{c}.png"));
        write_image(&p, &img, None).unwrap();
        assert_eq!(read_image(&p).unwrap(), img, "16-bit, {c} channel(s)");
        // The float readers see the same values (16-bit: value / 65535).
        if c == 1 {
            let Samples::U16(v) = &img.samples else { unreachable!() };
            assert_eq!(read_gray_f32(&p).unwrap().get(4, 2), v[2 * 5 + 4] as f32 / 65535.0);
        }
        // EXR: bit-exact floats, including values PNG cannot hold.
        let f: Vec<f32> = (0..n * c).map(|i| (i as f32 - 7.25) * 1e-3 + if i == 3 { 1e30 } else { 0.0 }).collect();
        let img = RawImage::new(w, h, c, Samples::F32(f)).unwrap();
        let p = d.join(format!("f32_{c}.exr"));
        write_image(&p, &img, None).unwrap();
        assert_eq!(read_image(&p).unwrap(), img, "EXR, {c} channel(s)");
        let named = read_exr_channels(&p).unwrap();
        let mut names: Vec<&str> = named.channels.iter().map(|(n, _)| n.as_str()).collect();
        names.sort();
        let mut want = default_channel_names(c).to_vec();
        want.sort();
        assert_eq!(names, want);
    }
    // Named EXR channels of any names, read back by name.
    let planes: Vec<(String, Vec<f32>)> = ["depth", "weight"]
        .iter()
        .enumerate()
        .map(|(k, name)| (name.to_string(), (0..n).map(|i| (k * 100 + i) as f32 + 0.5).collect()))
        .collect();
    let exr = ExrChannels { width: w, height: h, channels: planes };
    write_exr_channels(d.join("named.exr"), &exr).unwrap();
    let mut back = read_exr_channels(d.join("named.exr")).unwrap();
    back.channels.sort_by(|a, b| a.0.cmp(&b.0));
    assert_eq!(back, exr);
    // Two channels that are neither R G B nor Y: read_image asks for them by name.
    let e = read_image(d.join("named.exr")).unwrap_err();
    assert!(e.to_string().contains("read them by name") && e.to_string().contains("named.exr"), "{e}");
    // Interleaved channels with names of our choosing.
    let f: Vec<f32> = (0..n * 2).map(|i| i as f32).collect();
    let img = RawImage::new(w, h, 2, Samples::F32(f)).unwrap();
    let names = vec!["Z".to_string(), "W".to_string()];
    write_image(d.join("zw.exr"), &img, Some(&names)).unwrap();
    let back = read_exr_channels(d.join("zw.exr")).unwrap();
    let z = &back.channels.iter().find(|(n, _)| n == "Z").unwrap().1;
    let wv = &back.channels.iter().find(|(n, _)| n == "W").unwrap().1;
    assert_eq!((z[7], wv[7]), (14.0, 15.0));
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn exr_layers_are_all_read() {
    use exr::prelude::*;
    let d = tmp_dir("layers");
    let (w, h) = (4usize, 2usize);
    let layer = |name: &str, chans: &[(&str, f32)]| {
        let list: Vec<AnyChannel<FlatSamples>> =
            chans.iter().map(|(n, v)| AnyChannel::new(*n, FlatSamples::F32(vec![*v; w * h]))).collect();
        Layer::new((w, h), LayerAttributes::named(name), Encoding::SMALL_LOSSLESS, AnyChannels::sort(list.into()))
    };
    // Blender-style full names in one layer, and a second layer whose channel names lack the prefix.
    let layers = vec![
        layer("ViewLayer.Combined", &[("ViewLayer.Combined.R", 0.25), ("ViewLayer.Combined.G", 0.5)]),
        layer("ViewLayer.Depth", &[("Z", 2.0)]),
    ];
    let image = Image::from_layers(ImageAttributes::new(IntegerBounds::from_dimensions((w, h))), layers);
    image.write().to_file(d.join("multi.exr")).unwrap();
    let exr = read_exr_channels(d.join("multi.exr")).unwrap();
    assert_eq!((exr.width, exr.height), (4, 2));
    let get = |n: &str| exr.channels.iter().find(|(m, _)| m == n).map(|(_, v)| v[5]);
    assert_eq!(get("ViewLayer.Combined.R"), Some(0.25));
    assert_eq!(get("ViewLayer.Combined.G"), Some(0.5));
    assert_eq!(get("ViewLayer.Depth.Z"), Some(2.0));
    assert_eq!(exr.channels.len(), 3);
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn raw_image_errors_say_what_to_do() {
    let d = tmp_dir("rawerr");
    let f = RawImage::new(2, 2, 1, Samples::F32(vec![0.5; 4])).unwrap();
    let e = write_image(d.join("f.png"), &f, None).unwrap_err();
    assert!(e.to_string().contains("not floats") && e.to_string().contains("f.png"), "{e}");
    let u = RawImage::new(2, 2, 1, Samples::U8(vec![1; 4])).unwrap();
    let e = write_image(d.join("u.exr"), &u, None).unwrap_err();
    assert!(e.to_string().contains("OpenEXR stores floats"), "{e}");
    let e = write_image(d.join("u.tif"), &u, None).unwrap_err();
    assert!(matches!(e.kind, FormatErrorKind::UnknownExtension { .. }), "{e}");
    let e = write_image(d.join("u.png"), &u, Some(&["Y".to_string()])).unwrap_err();
    assert!(e.to_string().contains("channel names are for OpenEXR"), "{e}");
    let e = write_image(d.join("f.exr"), &f, Some(&["Y".to_string(), "A".to_string()])).unwrap_err();
    assert!(e.to_string().contains("2 channel names for an image of 1 channels"), "{e}");
    assert!(RawImage::new(2, 2, 5, Samples::U8(vec![0; 20])).is_err());
    assert!(RawImage::new(2, 2, 1, Samples::U8(vec![0; 3])).is_err());
    let e = read_image(d.join("missing.png")).unwrap_err();
    assert!(matches!(e.kind, FormatErrorKind::Io(_)) && e.to_string().contains("missing.png"), "{e}");
    std::fs::write(d.join("junk.png"), b"not an image at all").unwrap();
    let e = read_image(d.join("junk.png")).unwrap_err();
    assert!(matches!(e.kind, FormatErrorKind::BadMagic { .. }), "{e}");
    assert_eq!(std::fs::read_dir(&d).unwrap().count(), 1, "a failed write left a file");
    std::fs::remove_dir_all(&d).unwrap();
}

/// CRC-32 (PNG's chunk checksum), bit by bit.
fn crc32(bytes: &[u8]) -> u32 {
    let mut c = 0xFFFF_FFFFu32;
    for &b in bytes {
        c ^= b as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
        }
    }
    !c
}

#[test]
fn an_image_claiming_too_many_pixels_is_refused_before_decoding() {
    let d = tmp_dir("huge");
    let path = d.join("small.png");
    write_png8_gray(&path, &GrayImage32::filled(1, 1, 0.5)).unwrap();
    let mut png = std::fs::read(&path).unwrap();
    // IHDR starts at byte 8: length (4), "IHDR" (4), width (4), height (4), ..., CRC over type + data.
    assert_eq!(&png[12..16], b"IHDR");
    png[16..20].copy_from_slice(&20_000u32.to_be_bytes());
    png[20..24].copy_from_slice(&20_000u32.to_be_bytes());
    let crc = crc32(&png[12..29]);
    png[29..33].copy_from_slice(&crc.to_be_bytes());
    let huge = d.join("huge.png");
    std::fs::write(&huge, &png).unwrap();
    for e in [read_gray_f32(&huge).unwrap_err(), read_rgb_f32(&huge).unwrap_err(), read_image(&huge).unwrap_err()] {
        let msg = e.to_string();
        assert!(msg.contains("20000x20000") && msg.contains("huge.png"), "{msg}");
    }
    // 5000 x 5000 is within the pixel budget, but not in a file of a few dozen bytes: deflate cannot expand
    // that much, so the header lies (a truncated file, or a forged one).
    png[16..20].copy_from_slice(&5000u32.to_be_bytes());
    png[20..24].copy_from_slice(&5000u32.to_be_bytes());
    let crc = crc32(&png[12..29]);
    png[29..33].copy_from_slice(&crc.to_be_bytes());
    std::fs::write(&huge, &png).unwrap();
    let msg = read_image(&huge).unwrap_err().to_string();
    assert!(msg.contains("more than a file of") && msg.contains("truncated"), "{msg}");
    // The same header at 1x1 still decodes: the check is on the size, not the patching.
    png[16..20].copy_from_slice(&1u32.to_be_bytes());
    png[20..24].copy_from_slice(&1u32.to_be_bytes());
    let crc = crc32(&png[12..29]);
    png[29..33].copy_from_slice(&crc.to_be_bytes());
    std::fs::write(&huge, &png).unwrap();
    assert_eq!(read_gray_f32(&huge).unwrap().width, 1);
    let _ = std::fs::remove_dir_all(&d);
}

/// OpenEXR headers (found by the fuzzer, `scripts/fuzz.sh`) whose layers claim more samples than
/// the budget, or than their few hundred bytes could hold: one asked for 16 PB and aborted, one for
/// about a gigabyte that decoding held 2 GB for. Every reader refuses both from the header,
/// without allocating.
#[test]
fn an_exr_claiming_more_samples_than_the_budget_is_refused_before_decoding() {
    let files: [&[u8]; 2] = [
        include_bytes!("data/exr_header_claims_terabytes.exr"),
        include_bytes!("data/exr_header_claims_a_gigabyte.exr"),
    ];
    for bytes in files {
        let errors = [
            read_image_bytes(bytes).unwrap_err(),
            read_exr_channels_bytes(bytes).unwrap_err(),
            read_gray_f32_bytes(bytes).unwrap_err(),
            read_rgb_f32_bytes(bytes).unwrap_err(),
        ];
        for e in errors {
            let msg = e.to_string();
            assert!(msg.contains("more than the") || msg.contains("more than a file of"), "{msg}");
        }
    }
}
