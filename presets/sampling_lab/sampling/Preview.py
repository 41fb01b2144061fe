import bpy
settings = bpy.context.scene.sampling_lab

settings.integrator = 'PATH'
settings.sampler = 'SOBOL'
settings.samples = 16
settings.time_limit = 0.0
settings.max_bounces = 4
settings.use_russian_roulette = True
settings.rr_min_bounces = 3
settings.rr_survival = 'SQUARE_ROOT'
settings.mis_heuristic = 'POWER'
settings.mis_beta = 2.0
settings.mis_alpha = 0.1
settings.light_selection = 'TREE'
settings.light_sampling = 'AREA'
settings.distribution = 'CDF'
