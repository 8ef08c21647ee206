"""Networks, training, evaluation and the live engine, in one subpackage each.

    networks/    NVR and NVR+ (paper 3.3, 3.4): configurations, layers, weights files, inference copies
    training/    data sets as tensors, the loss of eq. 2 with its perceptual term, the training loop
    evaluation/  the metrics of the paper's table 1 and `nvr eval`
    engine/      the live renderer: cached stages, the worker thread, what keeps an edit's work small
    bench/       `nvr bench`: every renderer's speed against its error
"""
