"""The judge: reads rosbag2 recordings and analyses what the machine really did.

It imports nothing of cnc_planner: an independent judge must not share the planner's
assumptions. Geometry it needs (holes, R plane, thread form) comes in as plain numbers.
"""
