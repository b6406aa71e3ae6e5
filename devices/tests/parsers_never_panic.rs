//! Every parser takes arbitrary bytes without panicking: decoders return values or errors,
//! streaming readers resynchronise, and spec/profile parsing reports errors.

use dynaclay_devices::codec::frame::{DeviceMsg, FrameEvent, FrameReader, HostMsg};
use dynaclay_devices::codec::{
    cartesian, falcon, frame, haply_board, haply_service, spacemouse, woodenhaptics,
};
use dynaclay_devices::profile::DeviceProfile;
use dynaclay_devices::spec::DeviceSpec;
use proptest::prelude::*;

proptest! {
    #![proptest_config(ProptestConfig { cases: 4096, ..ProptestConfig::default() })]

    #[test]
    fn report_decoders_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..64)) {
        let _ = woodenhaptics::decode_status(&bytes);
        let _ = woodenhaptics::decode_command(&bytes);
        let _ = cartesian::decode_state(&bytes);
        let _ = cartesian::decode_command(&bytes);
        let _ = spacemouse::decode_report(&bytes);
        let _ = falcon::decode_status(&bytes);
        let _ = falcon::decode_command(&bytes);
        if let Ok((k, p)) = frame::decode_frame(&bytes) {
            let _ = HostMsg::decode(k, p);
            let _ = DeviceMsg::decode(k, p);
        }
        if let Some((&k, p)) = bytes.split_first() {
            let _ = HostMsg::decode(k, p);
            let _ = DeviceMsg::decode(k, p);
        }
    }

    #[test]
    fn streaming_readers_never_panic_and_find_embedded_frames(
        noise in proptest::collection::vec(any::<u8>(), 0..300),
        x in any::<i32>(), seq in any::<u16>(),
    ) {
        // Noise, then a valid frame: the reader must deliver that frame.
        let msg = DeviceMsg::State { position_um: [x, -x, 7], buttons: 1, seq, status: 0 };
        let mut buf = [0u8; frame::MAX_FRAME];
        let n = msg.encode(&mut buf).unwrap();
        let mut r = FrameReader::new();
        let mut found = false;
        // Enough trailing frames that a false sync in the noise cannot swallow them all.
        let stream: Vec<u8> = noise.iter().copied().chain((0..3).flat_map(|_| buf[..n].to_vec())).collect();
        for b in stream {
            let mut ev = Some(r.push(b));
            while let Some(e) = ev {
                if let FrameEvent::Frame { kind, .. } = e
                    && DeviceMsg::decode(kind, r.payload()) == Ok(msg) { found = true; }
                ev = r.drain();
            }
        }
        prop_assert!(found);

        let status = falcon::FalconStatus { encoders: [x as i16, 0, -1], buttons: 3, homed: 7 };
        let frame_bytes = falcon::encode_status(&status);
        let mut fr = falcon::FalconReader::new();
        let mut got = false;
        for b in noise.iter().copied().chain(frame_bytes) {
            if fr.push(b) == falcon::ReadEvent::Frame(status) { got = true; }
        }
        prop_assert!(got);
    }

    #[test]
    fn spec_and_profile_parsers_never_panic(s in "\\PC{0,40}", raw in proptest::collection::vec(any::<u8>(), 0..200)) {
        let _ = s.parse::<DeviceSpec>();
        let text = String::from_utf8_lossy(&raw);
        let _ = DeviceProfile::from_toml(&text, std::path::Path::new("fuzz.toml"));
        let _ = DeviceProfile::from_toml(&s, std::path::Path::new("fuzz.toml"));
    }

    #[test]
    fn haply_decoders_never_panic(
        raw in proptest::collection::vec(any::<u8>(), 0..40),
        text in "\\PC{0,200}",
        n in 0usize..6,
        x in any::<f64>(),
    ) {
        let mut angles = [0.0f32; 5];
        let _ = haply_board::decode_angles(5, &raw, &mut angles[..n.min(5)]);
        let _ = haply_service::parse_state(&text, None);
        let _ = haply_service::parse_state(&String::from_utf8_lossy(&raw), Some("049D"));
        // A well-formed message with any number where a coordinate goes.
        let msg = format!(
            r#"{{"inverse3":[{{"device_id":"049D","state":{{"cursor_position":{{"x":{x},"y":0,"z":0}},"cursor_velocity":{{"x":0,"y":0,"z":0}}}}}}]}}"#
        );
        match haply_service::parse_state(&msg, None) {
            // serde_json's fast float parsing may round the last bit differently.
            Ok(r) => prop_assert!((r.cursor_position_m[0] - x).abs() <= 1e-12 * x.abs()),
            Err(e) => prop_assert!(!x.is_finite(), "{e}"),
        }
    }

    #[test]
    fn falcon_frames_round_trip(m in any::<[i16; 3]>(), leds in 0u8..16, homing in any::<bool>()) {
        let c = falcon::FalconCommand { motor: m, leds: leds & 0xe, homing };
        prop_assert_eq!(falcon::decode_command(&falcon::encode_command(&c)), Ok(c));
    }
}
