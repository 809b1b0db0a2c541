# csws serve in a container: the bundled city (or CSWS_NETS), API keys from a mounted key file.
#   docker build -t csws .
#   csws keys add acme --role admin --file keys/api-keys.json     # on the host; prints the key once
#   docker run -p 8000:8000 -v "$PWD/keys:/etc/csws:ro" -v csws-state:/var/lib/csws csws
FROM python:3.11-slim

WORKDIR /opt/csws
COPY pyproject.toml README.md LICENSE ./
COPY csws ./csws
COPY service ./service
COPY networks ./networks
RUN pip install --no-cache-dir . && rm -rf /opt/csws

# The service reads its settings from CSWS_* variables: the fleets' key file (required on 0.0.0.0),
# where the vehicles' state and the fitted roads are kept.
ENV CSWS_API_KEYS_FILE=/etc/csws/api-keys.json \
    CSWS_STATE_DB=/var/lib/csws/vehicles.sqlite3 \
    CSWS_CACHE_DIR=/var/cache/csws
WORKDIR /var/lib/csws
EXPOSE 8000
CMD ["csws", "serve", "--host", "0.0.0.0", "--port", "8000"]
