"""identification: fit k_f and r of a rocking structure to measured free-vibration traces.

Built on rockjax's public API only. The fitting tools arrive with issue 4; this package
is the place they live.
"""
