# A small run of matedit.nets.train on the data of train.json (32 x 32 images, 16 x 32 lights):
#   matedit synth train.json -o train && matedit synth test.json -o test
#   python -m matedit.nets.train small.py --out runs/small
#   python -m matedit.nets.evaluate runs/small/weights.safetensors test
data = "train"
width = 16
levels = 3
steps = 300
batch_size = 16
lr = 2e-3
warmup = 20
render_loss = True
seed = 0
threads = 2
log_every = 25
checkpoint_every = 100
