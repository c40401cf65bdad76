use super::*;
use std::io::Write;

/// The stderr line for a fault at `addr`, if it is watched.
fn line_for(addr: usize) -> Option<String> {
    let mut text = [0u8; TEXT];
    let (offset, len) = find(addr, &mut text)?;
    let mut message = [0u8; MESSAGE];
    let m = format_message(&text[..len], offset, &mut message);
    let mut line = [0u8; LINE];
    let n = concat(&mut line, &[PREFIX, &message[..m], b"\n"]);
    Some(String::from_utf8(line[..n].to_vec()).unwrap())
}

/// Ranges are found with their file offsets and messages, and forgotten when dropped;
/// slots are reused. (Addresses far from anything mapped: nothing else registers them.)
#[test]
fn registered_ranges_name_their_file_and_byte() {
    let base = 0x1000_0000_0000usize;
    let a = Watch::new(base..base + 8192, 0, "brick cache", Path::new("/farm/a.plume"));
    let b = Watch::new(base + 8192..base + 12288, 4096, "VDB file", Path::new("/farm/b.vdb"));
    assert!(a.is_active() && b.is_active());
    let line = line_for(base + 100).unwrap();
    assert!(line.starts_with("plume: error: brick cache /farm/a.plume: byte 100 of the mapped file could not be read (SIGBUS"), "{line}");
    assert!(
        line.ends_with("nothing more was written\n") && line.matches('\n').count() == 1,
        "{line}"
    );
    assert!(line_for(base + 8192 + 5).unwrap().contains("VDB file /farm/b.vdb: byte 4101 of"));
    assert_eq!(line_for(base + 12288), None, "ranges are half-open");
    assert!(
        Watch::new(base..base, 0, "x", Path::new("y")).slot.is_none(),
        "an empty range is not registered"
    );
    drop(a);
    assert_eq!(line_for(base + 100), None);
    let c = Watch::new(base..base + 4096, 0, "brick cache", Path::new("/farm/c.plume"));
    assert!(line_for(base).unwrap().contains("/farm/c.plume: byte 0 of"));
    drop((b, c));
    assert_eq!(line_for(base + 8192), None);
}

#[test]
fn long_paths_keep_the_file_name_and_fit_the_slot() {
    let long = format!("/{}/é/frame.0001.plume", "d".repeat(3000));
    let text = message_text("brick cache", Path::new(&long));
    assert!(text.len() <= TEXT);
    let text = String::from_utf8(text).unwrap();
    assert!(text.starts_with("brick cache …") && text.ends_with("/é/frame.0001.plume"), "{text}");
    assert_eq!(
        String::from_utf8(message_text("k", Path::new("a\nb\tc"))).unwrap(),
        "k a?b?c",
        "one line"
    );
    let mut message = [0u8; MESSAGE];
    let n = format_message(long.as_bytes().get(..TEXT).unwrap(), u64::MAX - 1, &mut message);
    assert!(String::from_utf8_lossy(&message[..n]).contains(&format!(": byte {} of", u64::MAX - 1)));
    // A fault caught by `Watch::any_address` has no byte offset. (Not registered here:
    // it would claim other tests' addresses.)
    let n = format_message(b"VDB file /farm/b.vdb", ANY_ADDRESS, &mut message);
    let m = String::from_utf8_lossy(&message[..n]);
    assert!(
        m.starts_with("VDB file /farm/b.vdb: the mapped file could not be read (SIGBUS"),
        "{m}"
    );
}

/// The JSON event parses, with the message as its error, whatever quotes and
/// backslashes the path holds; the longest one fits.
#[test]
fn the_json_event_is_json() {
    for path in [r#"/farm/"q"\b.plume"#.to_string(), "\"".repeat(2000)] {
        let mut text = [0u8; TEXT];
        let t = message_text("brick cache", Path::new(&path));
        text[..t.len()].copy_from_slice(&t);
        let mut message = [0u8; MESSAGE];
        let m = format_message(&text[..t.len()], 12, &mut message);
        let mut event = [0u8; EVENT];
        let n = json_event(&message[..m], &mut event);
        assert_eq!(event[n - 1], b'\n');
        let v: serde_json::Value = serde_json::from_slice(&event[..n]).unwrap();
        assert_eq!(v["event"], "done");
        assert_eq!(v["exit_code"], 4);
        assert_eq!(v["error"].as_str().unwrap().as_bytes(), &message[..m]);
    }
}

#[test]
fn mappings_are_watched_and_found_in_proc_maps() {
    let path = std::env::temp_dir().join(format!("plume-mapfault-{}", std::process::id()));
    std::fs::File::create(&path).unwrap().write_all(&[7u8; 3 * 4096]).unwrap();
    let file = File::open(&path).unwrap();
    let map = Mapping::map(&file, &path, "brick cache").unwrap();
    assert!(map.is_watched());
    assert_eq!(map[4096], 7);
    let at = map.as_ptr() as usize + 4096 + 3;
    assert!(line_for(at).unwrap().contains(&format!("{}: byte 4099 of", path.display())));
    // The same mapping, found by device and inode
    let watches = watch_mappings_of(&path, "VDB file");
    assert_eq!(watches.len(), 1, "one mapping of the file");
    let slot = &REGISTRY[watches[0].slot.unwrap()];
    let mut text = [0u8; TEXT];
    let (offset, len) = slot.lookup(at, &mut text).unwrap();
    assert_eq!((offset, &text[..len]), (4099, format!("VDB file {}", path.display()).as_bytes()));
    drop(map);
    drop(watches);
    assert_eq!(slot.lookup(at, &mut text), None);
    let _ = std::fs::remove_file(&path);
}
