# cellrunner in a container: `docker build -t cellrunner .` then e.g.
#   docker run --rm cellrunner dry-run
#   docker run --rm --network host -v $PWD:/cell -w /cell cellrunner serve cells/line3.yaml
FROM python:3.11-slim

# What the wheels load from the system beyond the slim image (ldd of every .so they
# install): libgomp1 (pinocchio's OpenMP runtime: without it `import pinocchio` fails)
# and libquadmath0 (Boost's locale and charconv in the cmeel wheels). libosmesa6 and
# libgl1: offscreen pictures of the twin (dry-run --report) without a GPU or display.
RUN apt-get update \
    && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends \
        libgomp1 libquadmath0 libosmesa6 libgl1 \
    && rm -rf /var/lib/apt/lists/*
ENV MUJOCO_GL=osmesa PYTHONUNBUFFERED=1

WORKDIR /opt/cellrunner
COPY pyproject.toml README.md ./
COPY cellrunner ./cellrunner
RUN pip install --no-cache-dir .

# Modbus TCP (the cell file's plc.modbus.port) and OPC UA
EXPOSE 502 4840
ENTRYPOINT ["cellrunner"]
CMD ["--help"]
