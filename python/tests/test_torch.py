"""docs/python.md's PyTorch wrapper of mediareg.backward, where torch is installed: a few
Adam steps on a uniform grid lower the loss of the grid test scene's own image."""

import numpy as np
import pytest

import mediareg
from conftest import ROOT

torch = pytest.importorskip("torch")


class Render(torch.autograd.Function):
    @staticmethod
    def forward(ctx, density, path, vol, spp, seed):
        mediareg.write_vol(vol, density.detach().numpy())
        scene = mediareg.load_file(path, sigma_t_file=vol)
        ctx.scene, ctx.spp, ctx.seed = scene, spp, seed
        return torch.from_numpy(mediareg.render(scene, spp=spp, seed=seed))

    @staticmethod
    def backward(ctx, grad_image):
        g = mediareg.backward(ctx.scene, grad_image.numpy(), spp=ctx.spp, seed=ctx.seed + 1)
        return torch.from_numpy(g["sigma_t"]), None, None, None, None


def test_torch_loop_lowers_the_loss(tmp_path):
    path = str(ROOT / "mitsuba_scenes/grid_adjoint.xml")
    target = torch.from_numpy(mediareg.render(mediareg.load_file(path), spp=256, seed=9))
    density = torch.full((8, 8, 8), 0.3, requires_grad=True)
    opt = torch.optim.Adam([density], lr=0.05)
    losses = []
    for it in range(30):
        image = Render.apply(density, path, str(tmp_path / "x.vol"), 16, 2 * it)
        loss = ((image - target) ** 2).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
        with torch.no_grad():
            density.clamp_(0.0, 1.2)
        losses.append(loss.item())
    assert np.mean(losses[-5:]) < losses[0] / 3
