"""cellrunner.execution"""
