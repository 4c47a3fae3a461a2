//! MCAP reading throughput: `cargo run --release -p vgps-import --example mcap_throughput
//! [FILE.mcap]`. Without a file, writes a 256 MiB recording of 300 KB CompressedImage
//! messages (6 camera topics, 1 MiB chunks; once without compression, once with zstd) to
//! the temporary directory. Reads each file three times with `read_mcap_file`, decoding
//! every message's CDR, and prints the best MB/s (file bytes over wall time; the file is in
//! the page cache after the first read).
use std::borrow::Cow;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;
use vgps_import::mcap_read::read_mcap_file;
use vgps_import::ros_decode;

fn compressed_image_cdr(sec: i32, payload: &[u8]) -> Vec<u8> {
    let mut out = vec![0, 1, 0, 0];
    out.extend(sec.to_le_bytes());
    out.extend(0u32.to_le_bytes());
    out.extend(5u32.to_le_bytes());
    out.extend(b"cam0\0");
    while (out.len() - 4) % 4 != 0 {
        out.push(0);
    }
    out.extend(5u32.to_le_bytes());
    out.extend(b"jpeg\0");
    while (out.len() - 4) % 4 != 0 {
        out.push(0);
    }
    out.extend((payload.len() as u32).to_le_bytes());
    out.extend(payload);
    out
}

fn write_sample(path: &Path, compression: Option<mcap::Compression>) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).expect("create"));
    let mut w = mcap::WriteOptions::new()
        .compression(compression)
        .chunk_size(Some(1 << 20))
        .create(file)
        .expect("writer");
    let schema = Arc::new(mcap::Schema {
        id: 1,
        name: "sensor_msgs/msg/CompressedImage".into(),
        encoding: "ros2msg".into(),
        data: Cow::Borrowed(b""),
    });
    let channels: Vec<_> = (0..6)
        .map(|k| {
            Arc::new(mcap::Channel {
                id: k,
                topic: format!("/ladybug/cam{k}/image/compressed"),
                message_encoding: "cdr".into(),
                metadata: Default::default(),
                schema: Some(schema.clone()),
            })
        })
        .collect();
    // Pseudo-random bytes (an xorshift): JPEG data does not compress either.
    let mut x = 0x9e37_79b9_7f4a_7c15u64;
    let payload: Vec<u8> = (0..300_000)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x as u8
        })
        .collect();
    let n = (256 << 20) / payload.len();
    for i in 0..n {
        let data = compressed_image_cdr(i as i32, &payload);
        w.write(&mcap::Message {
            channel: channels[i % 6].clone(),
            sequence: i as u32,
            log_time: i as u64,
            publish_time: i as u64,
            data: Cow::Owned(data),
        })
        .expect("write");
    }
    w.finish().expect("finish");
}

fn measure(path: &Path) {
    let bytes = std::fs::metadata(path).expect("file").len() as f64;
    let mut best = f64::INFINITY;
    let mut messages = 0;
    for _ in 0..3 {
        let start = Instant::now();
        let mut image_bytes = 0usize;
        let summary = read_mcap_file(path, &mut |m| {
            if let Ok(img) = ros_decode::compressed_image(m.data) {
                image_bytes += img.data.len();
            }
        })
        .expect("read");
        best = best.min(start.elapsed().as_secs_f64());
        messages = summary.messages;
        assert!(image_bytes > 0 && summary.problems.is_empty());
    }
    println!(
        "{}: {:.0} MB, {messages} messages, best of 3: {:.3} s = {:.0} MB/s",
        path.display(),
        bytes / 1e6,
        best,
        bytes / 1e6 / best
    );
}

fn main() {
    if let Some(file) = std::env::args().nth(1) {
        measure(Path::new(&file));
        return;
    }
    let dir = std::env::temp_dir();
    for (name, c) in [("none", None), ("zstd", Some(mcap::Compression::Zstd))] {
        let path: PathBuf = dir.join(format!("vgps_throughput_{name}.mcap"));
        write_sample(&path, c);
        measure(&path);
        let _ = std::fs::remove_file(&path);
    }
}
