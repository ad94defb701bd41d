"""cellrunner.planning"""
