"""Videos the project writes are H.264 MP4 (browsers play it), decode frame for frame, appear
only when complete, and a simulator run through the drive server shows what the driver saw."""
import json

import av
import numpy as np
import pytest

from signlane.cli import main
from signlane.video_out import VideoOut
from signlane.world.sampling import FrameSampler, SamplerConfig


def decoded(path) -> tuple[str, str, list[np.ndarray]]:
    """(codec, pixel format, frames as BGR) of the first video stream."""
    with av.open(str(path)) as box:
        stream = box.streams.video[0]
        codec, pix = stream.codec_context.name, stream.codec_context.pix_fmt
        frames = [f.to_ndarray(format="bgr24") for f in box.decode(stream)]
    return codec, pix, frames


@pytest.fixture(scope="module")
def road():
    smp = FrameSampler(11, SamplerConfig(320, 240, effects="clean", randomise=False))
    return [smp.sample(i).image for i in range(12)]


def test_video_out_writes_h264_that_decodes_frame_for_frame(tmp_path, road):
    path = tmp_path / "v.mp4"
    with VideoOut(path, 30, (320, 240)) as video:
        for im in road:
            video.write(im)
        assert not path.exists()  # only a temporary until closed
    codec, pix, frames = decoded(path)
    assert codec == "h264" and pix == "yuv420p" and len(frames) == len(road)
    for got, want in zip(frames, road):
        assert got.shape == want.shape and np.mean(np.abs(got.astype(int) - want.astype(int))) < 6
    assert [p.name for p in tmp_path.iterdir()] == ["v.mp4"]


def test_a_failed_video_leaves_nothing_and_odd_sizes_are_trimmed(tmp_path, road):
    with pytest.raises(RuntimeError):
        with VideoOut(tmp_path / "broken.mp4", 10, (320, 240)) as video:
            video.write(road[0])
            raise RuntimeError("the drive failed")
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(ValueError, match="broken.mp4: frame of shape"):
        VideoOut(tmp_path / "broken.mp4", 10, (320, 240)).write(road[0][:100])
    odd = [im[:239, :319] for im in road[:3]]
    with VideoOut(tmp_path / "odd.mp4", 10, (319, 239)) as video:
        for im in odd:
            video.write(im)
    codec, _, frames = decoded(tmp_path / "odd.mp4")
    assert codec == "h264" and [f.shape for f in frames] == [(238, 318, 3)] * 3


def test_a_video_of_no_frames_says_so_and_leaves_nothing(tmp_path):
    with pytest.raises(ValueError, match="empty.mp4: no frames were written"):
        VideoOut(tmp_path / "empty.mp4", 10, (320, 240)).close()
    assert list(tmp_path.iterdir()) == []


def test_sim_without_a_server_says_only_that_and_leaves_no_video(tmp_path, capsys):
    import socket
    with socket.socket() as s:  # a port nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    out = tmp_path / "sim"
    assert main(["sim", "--url", f"ws://127.0.0.1:{port}", "--video", "--out", str(out), "--max-seconds", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert f"cannot reach the drive server at ws://127.0.0.1:{port}" in err
    assert "drive.mp4" not in err and not (out / "drive.mp4").exists()
    assert not out.exists() or not any(p.suffix == ".mp4" for p in out.iterdir())


def test_infer_writes_its_annotated_video_as_h264(tmp_path, road, capsys):
    src = tmp_path / "clip.mp4"
    with VideoOut(src, 10, (320, 240)) as video:
        for im in road[:6]:
            video.write(im)
    assert main(["infer", "--no-progress", str(src), "--out", str(tmp_path / "out")]) == 0
    codec, _, frames = decoded(tmp_path / "out" / "clip.mp4")
    assert codec == "h264" and len(frames) == 6


def test_sim_with_driver_video_shows_what_the_driver_saw(tmp_path, monkeypatch, capsys):
    import signlane.sim.session as session
    seen = []
    draw = session.annotate_drive

    def spy(image, perception, command, speed, t):  # the demo's own overlay, watched
        drawn = draw(image, perception, command, speed, t)
        seen.append((perception, command, image, drawn))
        return drawn
    monkeypatch.setattr(session, "annotate_drive", spy)
    out = tmp_path / "sim"
    assert main(["sim", "--with-driver", "--lockstep", "--video", "--out", str(out), "--size", "320x240",
                 "--max-seconds", "1.5"]) == 0
    codec, _, frames = decoded(out / "drive.mp4")
    assert codec == "h264" and len(frames) == len(seen) >= 40
    assert all(p is not None and p.lane.method and c.state != "remote" for p, c, _, _ in seen)
    for f, (_, _, raw, drawn) in zip(frames, seen):  # the video holds the overlaid frames, not the raw ones
        err = lambda a: np.mean(np.abs(f.astype(int) - a.astype(int)))  # noqa: E731
        assert err(drawn) < 6 and err(drawn) < err(raw)
    assert json.loads((out / "report.json").read_text())["time_s"] >= 1.4
