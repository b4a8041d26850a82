"""The smallest outside model, as the source of a builder file: a linear classifier of delay
images and its builder (``build``), which the tests of outside models, of misbehaving builders
and of ``simlidar evaluate`` write into files after their own imports (``from torch import
nn`` at least) and before their own builders. (tests/ is on sys.path: pytest puts the folder
of tests/conftest.py there.)"""

PLAIN_MODEL = """

class Plain(nn.Module):
    def __init__(self, pixels, classes):
        super().__init__()
        self.fc = nn.Linear(pixels, classes)

    def forward(self, x):
        return self.fc(x.flatten(1))


def build(input_shape, classes, generator=None, **kw):
    return Plain(input_shape[1] * input_shape[2], classes)
"""
