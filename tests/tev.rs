//! `hemi render --display-server`: the progressive image reaches a (fake) tev on the loopback
//! interface as tev's protocol says: one create-image packet, then update-image packets, the
//! last holding the final image.

use std::{io::Read, net::TcpListener, process::Command, thread};

/// One packet: its type and the bytes after the type.
fn packets(bytes: &[u8]) -> Vec<(u8, Vec<u8>)> {
    let mut out = Vec::new();
    let mut at = 0;
    while at + 5 <= bytes.len() {
        let len = u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
        assert!(len >= 5 && at + len <= bytes.len(), "truncated packet at {at}");
        out.push((bytes[at + 4], bytes[at + 5..at + len].to_vec()));
        at += len;
    }
    assert_eq!(at, bytes.len(), "trailing bytes");
    out
}

struct Reader<'a>(&'a [u8]);

impl Reader<'_> {
    fn u8(&mut self) -> u8 {
        let v = self.0[0];
        self.0 = &self.0[1..];
        v
    }
    fn u32(&mut self) -> u32 {
        let v = u32::from_le_bytes(self.0[..4].try_into().unwrap());
        self.0 = &self.0[4..];
        v
    }
    fn u64(&mut self) -> u64 {
        let v = u64::from_le_bytes(self.0[..8].try_into().unwrap());
        self.0 = &self.0[8..];
        v
    }
    fn str(&mut self) -> String {
        let end = self.0.iter().position(|&b| b == 0).unwrap();
        let s = String::from_utf8(self.0[..end].to_vec()).unwrap();
        self.0 = &self.0[end + 1..];
        s
    }
}

#[test]
fn render_streams_create_and_update_packets_to_tev() {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let address = listener.local_addr().unwrap().to_string();
    let server = thread::spawn(move || {
        let (mut stream, _) = listener.accept().unwrap();
        let mut bytes = Vec::new();
        stream.read_to_end(&mut bytes).unwrap();
        bytes
    });
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("hemi-tev");
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("streamed.exr");
    let status = Command::new(env!("CARGO_BIN_EXE_hemi"))
        .args(["render", "--size", "16x8", "--spp", "8", "--spf", "2", "--display-server", &address, "--out"])
        .arg(&out)
        .status()
        .unwrap();
    assert!(status.success());
    let bytes = server.join().unwrap();
    let packets = packets(&bytes);
    assert!(packets.len() >= 2, "{} packets", packets.len());

    let (kind, body) = &packets[0];
    assert_eq!(*kind, 4, "create image first");
    let mut r = Reader(body);
    r.u8();
    assert!(r.str().ends_with("streamed.exr"));
    assert_eq!((r.u32(), r.u32(), r.u32()), (16, 8, 3));
    assert_eq!((r.str(), r.str(), r.str()), ("R".into(), "G".into(), "B".into()));

    let mut last = Vec::new();
    for (kind, body) in &packets[1..] {
        assert_eq!(*kind, 6, "then update image (v3)");
        let mut r = Reader(body);
        r.u8();
        r.str();
        assert_eq!(r.u32(), 3);
        (0..3).for_each(|_| drop(r.str()));
        assert_eq!((r.u32(), r.u32(), r.u32(), r.u32()), (0, 0, 16, 8));
        assert_eq!((r.u64(), r.u64(), r.u64()), (0, 1, 2));
        assert_eq!((r.u64(), r.u64(), r.u64()), (3, 3, 3));
        last = r.0.chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().unwrap())).collect();
        assert_eq!(last.len(), 16 * 8 * 3);
    }
    // The last update is the finished image.
    let exr = image::open(&out).unwrap().into_rgb32f();
    assert_eq!(last, exr.as_raw().to_vec());
}

#[test]
fn an_unreachable_display_server_is_one_line_and_a_non_zero_exit() {
    // A port nobody listens on: bind one, then close it.
    let address = TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().to_string();
    let out = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("hemi-tev-none.png");
    let output = Command::new(env!("CARGO_BIN_EXE_hemi"))
        .args(["render", "--size", "8x8", "--spp", "1", "--display-server", &address, "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(!output.status.success());
    let err = String::from_utf8_lossy(&output.stderr);
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(err.contains("--display-server") && err.contains("cannot connect"), "{err}");
}
