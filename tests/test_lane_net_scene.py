"""The lane net's frame-wide parts: the frame's own contrast at the stem, the whole frame's
features at 1/8, the road surface's Dice term, and nets trained before them still loading."""
import torch

from signlane_train.lane_net import ImageContrast, LaneSegNet, SceneContext


def test_contrast_channels_ignore_a_frames_exposure_and_keep_the_raw_ones():
    g = torch.Generator().manual_seed(0)
    x = torch.randn(2, 3, 24, 32, generator=g)
    # a darker, flatter and tinted copy of the same frame: per-channel gain and offset
    gain, offset = torch.tensor([0.2, 0.3, 0.25]).view(1, 3, 1, 1), torch.tensor([-1.5, -1.2, -1.4]).view(1, 3, 1, 1)
    y = ImageContrast(eps=1e-4)(torch.cat([x, x * gain + offset]))
    assert y.shape == (4, 6, 24, 32)
    assert torch.equal(y[2:, :3], x * gain + offset)  # the raw channels pass as they are
    assert torch.allclose(y[:2, 3:], y[2:, 3:], atol=1e-3)  # the normalised ones match
    assert torch.allclose(y[:, 3:].mean(dim=(2, 3)), torch.zeros(4, 3), atol=1e-5)
    # a flat frame stays flat instead of blowing its noise up
    flat = torch.full((1, 3, 8, 8), 0.7) + 1e-3 * torch.randn(1, 3, 8, 8, generator=g)
    assert ImageContrast()(flat)[:, 3:].abs().max() < 0.1


def test_scene_context_reaches_every_pixel():
    ctx = SceneContext(4)
    x = torch.zeros(1, 4, 6, 8)
    x[0, :, 0, 0] = 50.0  # one corner pixel changes what every other pixel gets
    with torch.no_grad():
        for p in ctx.mix.parameters():
            p.copy_(torch.ones_like(p) if p.dim() > 1 else torch.zeros_like(p))
        y = ctx(x)
    assert torch.allclose(y[0, :, 5, 7], torch.full((4,), 4 * 50.0 / 48))


def test_scene_net_shapes_and_the_net_before_it():
    old, new = LaneSegNet(4, 8), LaneSegNet(4, 8, scene=True)
    assert old.stem[0].in_channels == 3 and new.stem[0].in_channels == 6
    x = torch.randn(2, 3, 120, 160)
    assert new.eval()(x).shape == old.eval()(x).shape == (2, 4, 120, 160)
    # a checkpoint of the net before (no `scene` hyperparameter) loads into a net built as it was
    from signlane_train.lane_task import LaneTask
    task = LaneTask(width=8, drivable=True)
    assert task.hparams.scene is False and task.net.stem[0].in_channels == 3
    LaneTask(width=8, drivable=True, scene=False).net.load_state_dict(old.state_dict())


def test_drivable_dice_adds_the_surface_overlap_to_the_loss():
    from signlane_train.lane_task import LaneTask, dice_loss
    torch.manual_seed(0)
    logits = torch.randn(2, 4, 12, 16)
    y = torch.randint(0, 2, (2, 12, 16))
    road = torch.randint(0, 2, (2, 12, 16))
    road[0, :3] = 255  # unlabelled pixels count nowhere
    plain = LaneTask(width=8, drivable=True)._loss(logits, y, road)
    with_dice = LaneTask(width=8, drivable=True, drivable_dice=0.5)._loss(logits, y, road)
    assert torch.isclose(with_dice - plain, 0.5 * dice_loss(logits[:, 2:4], road))
    # a perfect surface has no Dice left to lose
    sure = torch.where(road == 1, 20.0, -20.0).float()
    perfect = torch.stack([-sure, sure], 1)
    assert dice_loss(perfect, road) < 1e-3


def test_a_negative_drivable_dice_is_one_line(tmp_path, capsys):
    from signlane.cli import main
    assert main(["train", "lanes", str(tmp_path), "--out", str(tmp_path / "run"), "--drivable-dice", "-1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["signlane train: error: --drivable-dice -1.0: must be >= 0"] and not (tmp_path / "run").exists()
