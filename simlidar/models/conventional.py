"""Conventional baselines in plain torch: the paper's CNN, VGG and ResNet for small inputs.

Layer plans are data, as torchvision writes them (``VGG_PLANS``, ``RESNET_PLANS``); the
adaptations to small single-channel inputs (a 16 x 16 Sim LiDAR sample, a 50 x 118 KITTI crop)
are: one input channel; a 3 x 3 stride-1 stem for ResNet instead of 7 x 7 stride 2 plus max
pool; VGG skips a max pool once a side is down to 1 pixel; global average pooling and one small
classifier instead of VGG's 4096-4096 head; batch norm in VGG (torchvision's ``vgg16_bn``) so it
trains from scratch. There are no pretrained weights: every model starts from its seeded
initialisation. Weights are initialised from the ``torch.Generator`` passed in, never from the
global random state, so a seed fixes a model.
"""

import math

import torch
from torch import nn

from simlidar.errors import ConfigError
from simlidar.models.layers import check_layer
from simlidar.models.protocol import ModelSpec

# torchvision's cfgs: channels of 3 x 3 convolutions, "M" = 2 x 2 max pool
VGG_PLANS: dict[str, list] = {
    "vgg11": [64, "M", 128, "M", 256, 256, "M", 512, 512, "M", 512, 512, "M"],
    "vgg16": [64, 64, "M", 128, 128, "M", 256, 256, 256, "M", 512, 512, 512, "M",
              512, 512, 512, "M"],
}  # fmt: skip
# block kind and blocks per stage (torchvision's resnet18 / resnet50)
RESNET_PLANS: dict[str, tuple[str, list[int]]] = {
    "resnet18": ("basic", [2, 2, 2, 2]),
    "resnet34": ("basic", [3, 4, 6, 3]),
    "resnet50": ("bottleneck", [3, 4, 6, 3]),
}


class Conventional(nn.Module):
    """Base of the shipped baselines: outputs are logits (B, classes) of delay images; the
    class is their argmax (:mod:`simlidar.models.protocol`)."""

    simlidar_spec = ModelSpec()
    event_driven = False  # no spikes to run event by event


def init_weights(model: nn.Module, generator: torch.Generator | None) -> nn.Module:
    """Kaiming-normal convolutions, uniform linear layers (torchvision's scheme), seeded."""
    for m in model.modules():
        if isinstance(m, nn.Conv2d):
            nn.init.kaiming_normal_(
                m.weight, mode="fan_out", nonlinearity="relu", generator=generator
            )
        elif isinstance(m, nn.Linear):
            bound = 1.0 / math.sqrt(m.in_features)
            nn.init.uniform_(m.weight, -bound, bound, generator=generator)
            nn.init.uniform_(m.bias, -bound, bound, generator=generator)
        elif isinstance(m, nn.BatchNorm2d):
            nn.init.ones_(m.weight)
            nn.init.zeros_(m.bias)
        if isinstance(m, nn.Conv2d) and m.bias is not None:
            nn.init.zeros_(m.bias)
    return model


class CNN(Conventional):
    """The SCNN's architecture with ReLU: conv (channels, kernel, stride)... then dense...

    x : (B, C, H, W) delays -> (B, classes) logits
    """

    def __init__(self, input_shape, classes, conv, dense):
        super().__init__()
        c, h, w = input_shape
        layers: list[nn.Module] = []
        for channels, kernel, stride in conv:
            pad = kernel // 2
            check_layer(c * kernel * kernel, channels, "convolution")
            layers += [nn.Conv2d(c, channels, kernel, stride, pad), nn.ReLU()]
            c = channels
            h, w = (h + 2 * pad - kernel) // stride + 1, (w + 2 * pad - kernel) // stride + 1
        layers.append(nn.Flatten())
        sizes = [c * h * w, *dense]
        for a, b in zip(sizes, sizes[1:]):
            check_layer(a, b, "dense layer")
            layers += [nn.Linear(a, b), nn.ReLU()]
        layers.append(nn.Linear(sizes[-1], classes))
        self.net = nn.Sequential(*layers)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x)


class VGG(Conventional):
    """VGG with batch norm from a plan; pools skipped once a side is 1; GAP + classifier."""

    def __init__(self, input_shape, classes, plan, classifier):
        super().__init__()
        c, h, w = input_shape
        layers: list[nn.Module] = []
        for item in plan:
            if item == "M":
                if min(h, w) >= 2:
                    layers.append(nn.MaxPool2d(2))
                    h, w = h // 2, w // 2
                continue
            layers += [nn.Conv2d(c, item, 3, padding=1), nn.BatchNorm2d(item), nn.ReLU()]
            c = item
        self.features = nn.Sequential(*layers)
        sizes = [c, *classifier]
        head: list[nn.Module] = [nn.AdaptiveAvgPool2d(1), nn.Flatten()]
        for a, b in zip(sizes, sizes[1:]):
            head += [nn.Linear(a, b), nn.ReLU()]
        head.append(nn.Linear(sizes[-1], classes))
        self.classifier = nn.Sequential(*head)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.classifier(self.features(x))


class BasicBlock(nn.Module):
    expansion = 1

    def __init__(self, c_in: int, width: int, stride: int):
        super().__init__()
        c_out = width * self.expansion
        self.body = nn.Sequential(
            nn.Conv2d(c_in, width, 3, stride, 1, bias=False), nn.BatchNorm2d(width), nn.ReLU(),
            nn.Conv2d(width, c_out, 3, 1, 1, bias=False), nn.BatchNorm2d(c_out),
        )  # fmt: skip
        self.skip = _projection(c_in, c_out, stride)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.relu(self.body(x) + self.skip(x))


# torchvision's two residual blocks, kept apart as there (alike in form, other layers)
class Bottleneck(nn.Module):
    """1x1 reduce, 3x3 (stride here, as torchvision's v1.5), 1x1 expand by 4."""

    expansion = 4

    def __init__(self, c_in: int, width: int, stride: int):
        super().__init__()
        c_out = width * self.expansion
        self.body = nn.Sequential(
            nn.Conv2d(c_in, width, 1, bias=False), nn.BatchNorm2d(width), nn.ReLU(),
            nn.Conv2d(width, width, 3, stride, 1, bias=False), nn.BatchNorm2d(width), nn.ReLU(),
            nn.Conv2d(width, c_out, 1, bias=False), nn.BatchNorm2d(c_out),
        )  # fmt: skip
        self.skip = _projection(c_in, c_out, stride)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.relu(self.body(x) + self.skip(x))


def _projection(c_in: int, c_out: int, stride: int) -> nn.Module:
    if stride == 1 and c_in == c_out:
        return nn.Identity()
    return nn.Sequential(nn.Conv2d(c_in, c_out, 1, stride, bias=False), nn.BatchNorm2d(c_out))


class ResNet(Conventional):
    """ResNet from a plan: 3x3 stem, four stages (widths 64..512, stride 2 from the second)."""

    def __init__(self, input_shape, classes, block, stages, width=64):
        super().__init__()
        kind = {"basic": BasicBlock, "bottleneck": Bottleneck}[block]
        layers: list[nn.Module] = [
            nn.Conv2d(input_shape[0], width, 3, 1, 1, bias=False),
            nn.BatchNorm2d(width),
            nn.ReLU(),
        ]
        c = width
        for stage, blocks in enumerate(stages):
            for b in range(blocks):
                stride = 2 if stage > 0 and b == 0 else 1
                layers.append(kind(c, width * 2**stage, stride))
                c = width * 2**stage * kind.expansion
        self.features = nn.Sequential(*layers)
        head = [nn.AdaptiveAvgPool2d(1), nn.Flatten(), nn.Linear(c, classes)]
        self.classifier = nn.Sequential(*head)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.classifier(self.features(x))


def cnn(input_shape, classes, generator=None, conv=((48, 5, 2), (24, 5, 2)), dense=(256,)):
    """The paper's CNN baseline: the SCNN's layers with ReLU (conv 5x5/2 x48, x24, dense 256).

    input_shape : (C, H, W) of one delay image, from the dataset
    classes : the logits it outputs, one per class
    generator : the ``torch.Generator`` the initial weights are drawn from (None: torch's global
        random state)
    conv : (channels, kernel, stride) of each convolution, in order, each zero-padded by
        kernel // 2 and followed by a ReLU
    dense : the widths of the ReLU dense layers after the convolutions; a last dense layer gives
        the logits
    """
    return init_weights(CNN(input_shape, classes, conv, dense), generator)


def mlp(input_shape, classes, generator=None, dense=(400,)):
    """A ReLU MLP, inputs - dense... - classes (``baselines/mlp.toml``: the dense SNN's shape,
    256-400-32): the CNN's layers without convolutions, the same modules and initialisation."""
    return init_weights(CNN(input_shape, classes, (), dense), generator)


def vgg(input_shape, classes, generator=None, plan="vgg16", classifier=(512,)):
    """VGG (``plan``: a name in VGG_PLANS or a list) with batch norm, for small inputs.

    input_shape : (C, H, W) of one delay image, from the dataset
    classes : the logits it outputs, one per class
    generator : the ``torch.Generator`` the initial weights are drawn from (None: torch's global
        random state)
    plan : a name in :data:`VGG_PLANS` (another name is a ConfigError), or a list in their
        form: the channels of each 3 x 3 convolution (with batch norm and ReLU) and "M" for a
        2 x 2 max pool (skipped once a side is 1 pixel)
    classifier : the widths of the ReLU dense layers after the global average pooling; a last
        dense layer gives the logits
    """
    if isinstance(plan, str) and plan not in VGG_PLANS:
        raise ConfigError(f"plan={plan!r}: expected one of {sorted(VGG_PLANS)} or a list")
    layers = VGG_PLANS[plan] if isinstance(plan, str) else plan
    return init_weights(VGG(input_shape, classes, layers, classifier), generator)


def resnet(input_shape, classes, generator=None, plan="resnet50", width=64):
    """ResNet (``plan``: a name in RESNET_PLANS) with a small-input stem.

    input_shape : (C, H, W) of one delay image, from the dataset
    classes : the logits it outputs, one per class
    generator : the ``torch.Generator`` the initial weights are drawn from (None: torch's global
        random state)
    plan : a name in :data:`RESNET_PLANS` (its block kind and blocks per stage); another name is
        a ConfigError
    width : the stem's channels and the first stage's block width, doubled at each later stage
        (a bottleneck block puts out 4 times its width); 64 is torchvision's
    """
    if plan not in RESNET_PLANS:
        raise ConfigError(f"plan={plan!r}: expected one of {sorted(RESNET_PLANS)}")
    block, stages = RESNET_PLANS[plan]
    return init_weights(ResNet(input_shape, classes, block, stages, width), generator)
