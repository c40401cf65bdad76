//! The parent's parser of the isolated reader's reply (`plume::vdb::wire`): whatever a
//! derailed child writes, parsing must return an error, never panic, hang or allocate
//! beyond its limits. libFuzzer's `-rss_limit_mb` (default 2048) catches an allocation
//! sized from an unchecked length; the bulk limit here is 16 MiB per grid.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = plume::vdb::wire::parse_reply(data, 16 << 20);
});
